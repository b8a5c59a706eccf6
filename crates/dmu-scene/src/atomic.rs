//! The one way dmu writes a file: into a temporary file beside the target,
//! synced, then renamed over it, and the directory synced. A crash, a full disk
//! or a kill at any moment leaves the previous file whole (or no file), never a
//! torn one. Stores, glTF, PNG images and JSON reports all go through here.

use std::fs::{File, OpenOptions};
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// A file being written under a temporary name (`.NAME.tmpPID-N` beside the
/// target): [`AtomicFile::commit`] renames it into place; dropping it removes
/// it, leaving the target as it was.
#[derive(Debug)]
pub struct AtomicFile {
    target: PathBuf,
    temp: PathBuf,
    file: File,
    committed: bool,
}

impl AtomicFile {
    /// Starts a file that will replace `path` when committed. Temporary files
    /// left beside `path` by writers that died are removed first.
    /// A target that exists and is not a regular file (a device such as
    /// `/dev/null`, a pipe, a folder) is refused: renaming over it would
    /// replace it.
    /// A symbolic link is followed: the file it names is replaced, the link
    /// kept; a link to nothing is refused.
    pub fn create(path: &Path) -> std::io::Result<AtomicFile> {
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let linked;
        let path = match std::fs::symlink_metadata(path) {
            Ok(meta) if meta.file_type().is_symlink() => {
                linked = path.canonicalize().map_err(|_| {
                    std::io::Error::other("a symbolic link to nothing (or a loop of links)")
                })?;
                linked.as_path()
            }
            _ => path,
        };
        if let Ok(meta) = std::fs::metadata(path)
            && !meta.is_file()
        {
            return Err(std::io::Error::other(
                "it exists and is not a regular file (a device, pipe or folder): dmu writes only files",
            ));
        }
        let name = path
            .file_name()
            .ok_or_else(|| std::io::Error::other("the path has no file name"))?;
        let mut temp_name = std::ffi::OsString::from(".");
        temp_name.push(name);
        temp_name.push(format!(
            ".tmp{}-{}",
            std::process::id(),
            COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        let temp = path.with_file_name(temp_name);
        remove_stale_temps(path);
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .create_new(true)
            .open(&temp)?;
        Ok(AtomicFile {
            target: path.to_owned(),
            temp,
            file,
            committed: false,
        })
    }

    /// The file to write (its cursor starts at 0).
    pub fn file(&mut self) -> &mut File {
        &mut self.file
    }

    /// The temporary file's path.
    pub fn temp_path(&self) -> &Path {
        &self.temp
    }

    /// The path it will replace.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Syncs the written bytes to disk (done again by [`AtomicFile::commit`]).
    pub fn sync(&mut self) -> std::io::Result<()> {
        self.file.sync_all()
    }

    /// Syncs, renames the file into place (atomic on one file system) and syncs
    /// the directory so the rename survives a power cut.
    pub fn commit(mut self) -> std::io::Result<()> {
        self.file.sync_all()?;
        std::fs::rename(&self.temp, &self.target)?;
        self.committed = true;
        let dir = folder_of(&self.target);
        // Directories cannot be opened for syncing everywhere; the rename itself
        // has happened, so a failure here only weakens durability.
        if let Ok(d) = File::open(dir) {
            let _ = d.sync_all();
        }
        Ok(())
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if !self.committed {
            // Best effort: the file is a leftover either way.
            let _ = std::fs::remove_file(&self.temp);
        }
    }
}

/// Opens a file for reading, refusing anything that is not a regular file
/// before opening it: a pipe would block the reader forever, a device such as
/// `/dev/zero` never ends, a folder is no model. Every input file dmu reads
/// goes through here.
pub fn open_regular_file(path: &Path) -> std::io::Result<File> {
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(std::io::Error::other(
            "not a regular file (a device, pipe or folder): dmu reads only files",
        ));
    }
    File::open(path)
}

/// The whole of a regular file (see [`open_regular_file`]).
pub fn read_regular_file(path: &Path) -> std::io::Result<Vec<u8>> {
    use std::io::Read as _;
    let mut bytes = Vec::new();
    open_regular_file(path)?.read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// Writes `bytes` to `path` through an [`AtomicFile`].
pub fn write_file_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let mut file = AtomicFile::create(path)?;
    file.file().write_all(bytes)?;
    file.commit()
}

/// The folder `path` is in: its parent, or `.` for a bare file name.
pub fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Removes temporary files left beside `path` by writers that died mid-write
/// (`.NAME.tmpPID-N` of a process that no longer runs), so killed saves do not
/// pile up copies of a large file. Only where `/proc` tells which processes
/// run; elsewhere nothing is removed.
fn remove_stale_temps(path: &Path) {
    let (Some(name), true) = (path.file_name(), Path::new("/proc/self").exists()) else {
        return;
    };
    let dir = folder_of(path);
    let prefix = format!(".{}.tmp", name.to_string_lossy());
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let file_name = entry.file_name();
        let pid = file_name
            .to_string_lossy()
            .strip_prefix(&prefix)
            .and_then(|rest| rest.split_once('-'))
            .and_then(|(pid, _)| pid.parse::<u32>().ok());
        if let Some(pid) = pid
            && pid != std::process::id()
            && !Path::new(&format!("/proc/{pid}")).exists()
        {
            // Best effort: a file that cannot be removed stays a leftover.
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A write that is dropped before commit leaves the old file byte for byte
    /// and no temporary file; a commit replaces it whole.
    #[test]
    fn only_a_commit_replaces_the_target() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        std::fs::write(&path, b"old").unwrap();
        {
            let mut f = AtomicFile::create(&path).unwrap();
            f.file().write_all(b"new but abandoned").unwrap();
        }
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        write_file_atomically(&path, b"new").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        // Through a link the linked file is replaced and the link kept; a
        // dangling link is refused.
        let link = dir.path().join("link.txt");
        std::os::unix::fs::symlink(&path, &link).unwrap();
        write_file_atomically(&link, b"via link").unwrap();
        assert!(
            std::fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(std::fs::read(&path).unwrap(), b"via link");
        let dangling = dir.path().join("dangling.txt");
        std::os::unix::fs::symlink(dir.path().join("nowhere/x"), &dangling).unwrap();
        assert!(write_file_atomically(&dangling, b"x").is_err());
        assert!(!dir.path().join("nowhere").exists());
    }
}
