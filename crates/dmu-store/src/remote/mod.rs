//! Stores on object storage and web servers: `s3://bucket/key` on S3 or a
//! server that speaks its API (SeaweedFS, MinIO), and `http://` or
//! `https://` addresses on any server that answers range requests. A store
//! read this way is checked exactly as a local one: every segment against
//! its checksum, every count against the bytes that hold it.
//!
//! Where and as whom (`RemoteOptions::from_env`, the AWS variables):
//! `AWS_ENDPOINT_URL` (else AWS's own endpoint for the region),
//! `AWS_REGION` or `AWS_DEFAULT_REGION` (default `us-east-1`), and
//! `AWS_ACCESS_KEY_ID` with `AWS_SECRET_ACCESS_KEY` (signed requests; none:
//! anonymous).
//!
//! **Reading** goes through a read-through cache on local disk
//! ((`remote/cache.rs`)): the object is read in blocks of [`BLOCK_BYTES`], each kept
//! under a key made of the address and the object's ETag, so a replaced
//! object never mixes with blocks of the one it replaced. The blocks a read
//! misses are fetched together: each run of adjacent missing blocks is one
//! range request (cut at [`MAX_REQUEST_BYTES`], with up to [`IN_FLIGHT`]
//! requests at once). A request that fails for the network or a server
//! error is retried [`RETRIES`] times; every request, retry and timeout is
//! counted ([`RemoteStats`]).
//!
//! **Writing** (`s3://` only, `remote/upload.rs`): the store is written to a local
//! file first, then put whole or in
//! parts of [`PART_BYTES`]. A rewrite of a store read from object storage (a save of edits,
//! new far fields) is a conditional put on the version it read: when
//! someone else saved the object in between, nothing is overwritten and the
//! new store is kept in a local file the error names.

pub(crate) mod cache;
pub(crate) mod upload;

pub use upload::PART_BYTES;

use std::io::{Error, ErrorKind, Read as _};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use rusty_s3::{Bucket, Credentials, S3Action, UrlStyle};

use crate::format::ReadAt;
use cache::BlockCache;

/// How long a signed request stays valid.
const REQUEST_TTL: Duration = Duration::from_secs(300);
/// How long connecting may take before the request fails.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(10);
/// How long each read of an answer may take: a server that stops answering
/// is an error, never a hang.
const READ_TIMEOUT: Duration = Duration::from_secs(20);
/// Retries of a request that failed for the network or a server error
/// (5xx, 429), after 100 ms, then 400 ms: at most three tries.
pub const RETRIES: u32 = 2;
/// The cache's block: what one read rounds up to. Measured on the 10M
/// plant's walk over 20 ms and 100 Mbit/s with 8 loaders (cold cache, first
/// complete image): 7.07 s at 64 KiB against 7.5-7.6 s at 256 KiB, for 3.4
/// times the requests (docs/measurements.md); the chunk segments average
/// 38 KB, so a larger block fetches neighbours the view may not want.
pub const BLOCK_BYTES: u64 = 64 << 10;
/// The most one range request asks for; a longer run is cut into requests
/// made in parallel.
pub const MAX_REQUEST_BYTES: u64 = 8 << 20;
/// Range requests one read makes at once.
pub const IN_FLIGHT: usize = 4;
/// The most one read asks for: past the largest segment a store holds (a
/// 500M plant's skeleton is about 140 MB), so that an object whose server
/// claims an absurd length cannot make dmu allocate it.
pub const MAX_READ_BYTES: u64 = 4 << 30;
/// How long one request may take in all, however slowly its bytes trickle
/// (8 MiB at 1 Mbit/s takes 67 s).
const REQUEST_TIMEOUT: Duration = Duration::from_secs(300);
/// The cache's default size on disk.
pub const DEFAULT_CACHE_BUDGET: u64 = 4 << 30;

/// Where object storage is, who asks, and where its blocks are cached.
#[derive(Clone, Debug, Default)]
pub struct RemoteOptions {
    /// The server, e.g. `http://127.0.0.1:8333`; `None` for AWS.
    pub endpoint: Option<String>,
    /// The region (AWS's, or any name the server accepts).
    pub region: String,
    /// Access key and secret; `None` for anonymous requests.
    pub credentials: Option<(String, String)>,
    /// The read-through cache's folder; `None`: no cache (every read is a
    /// request). Stores written to object storage are spooled here first.
    pub cache_dir: Option<PathBuf>,
    /// The most bytes the cache keeps on disk (least recently used blocks
    /// go first); 0: no cache.
    pub cache_budget: u64,
    /// The parts of a multipart upload (`None`: [`PART_BYTES`]; at least
    /// 5 MiB); a store over one part goes up in parts.
    pub part_bytes: Option<u64>,
}

/// The cache settings a command line gave ([`set_cache`]), over the
/// variables.
static CACHE: OnceLock<(Option<PathBuf>, Option<u64>)> = OnceLock::new();

/// Sets this process's cache folder and budget (the command line's
/// `--cache-dir` and `--cache-budget`), over `DMU_CACHE_DIR` and
/// `DMU_CACHE_BUDGET`; the first call wins.
pub fn set_cache(dir: Option<PathBuf>, budget: Option<u64>) {
    let _ = CACHE.set((dir, budget));
}

impl RemoteOptions {
    /// From the AWS variables (see the module's documentation), with the
    /// cache in `--cache-dir`, else `DMU_CACHE_DIR`, else
    /// `$XDG_CACHE_HOME/dmu`, else `~/.cache/dmu`, holding at most
    /// `--cache-budget`, else `DMU_CACHE_BUDGET` bytes (default
    /// [`DEFAULT_CACHE_BUDGET`]; 0 turns the cache off).
    pub fn from_env() -> Self {
        let var = |k: &str| std::env::var(k).ok().filter(|v| !v.is_empty());
        let (dir, budget) = CACHE.get().cloned().unwrap_or_default();
        let cache_dir = dir
            .or_else(|| var("DMU_CACHE_DIR").map(PathBuf::from))
            .or_else(|| {
                var("XDG_CACHE_HOME")
                    .map(PathBuf::from)
                    .or_else(|| var("HOME").map(|h| Path::new(&h).join(".cache")))
                    .map(|c| c.join("dmu"))
            });
        let cache_budget = budget
            .or_else(|| var("DMU_CACHE_BUDGET").and_then(|b| b.parse().ok()))
            .unwrap_or(DEFAULT_CACHE_BUDGET);
        Self {
            endpoint: var("AWS_ENDPOINT_URL"),
            region: var("AWS_REGION")
                .or_else(|| var("AWS_DEFAULT_REGION"))
                .unwrap_or_else(|| "us-east-1".into()),
            credentials: var("AWS_ACCESS_KEY_ID").zip(var("AWS_SECRET_ACCESS_KEY")),
            cache_dir,
            cache_budget,
            part_bytes: None,
        }
    }
}

/// Whether `path` names an object (`s3://bucket/key`) or a web address
/// (`http://`, `https://`) rather than a file.
pub fn is_remote(path: &Path) -> bool {
    path.to_str().is_some_and(|s| {
        ["s3://", "http://", "https://"]
            .iter()
            .any(|p| s.starts_with(p))
    })
}

/// Where a store bound for object storage is written first (and kept when
/// its upload meets a conflict): `kept/` in the cache folder, else in the
/// temporary folder; named after the object, the time, the process and a
/// count.
pub fn spool_path(url: &str, options: &RemoteOptions) -> std::io::Result<PathBuf> {
    let dir = options
        .cache_dir
        .clone()
        .unwrap_or_else(|| std::env::temp_dir().join("dmu"))
        .join("kept");
    std::fs::create_dir_all(&dir)?;
    let name = Path::new(url.rsplit('/').next().unwrap_or("store"));
    let stem = name
        .file_stem()
        .map_or("store".into(), |s| s.to_string_lossy())
        .replace(
            |c: char| !c.is_ascii_alphanumeric() && c != '-' && c != '_',
            "_",
        );
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    Ok(dir.join(format!("{stem}-{secs}-{}-{n}.dmu", std::process::id())))
}

/// Puts the local store `file` as the object `url` (`s3://` only), whole
/// or in parts, overwriting what is there: e.g. `dmu import`'s result,
/// built locally (see [`spool_path`]) and put once whole.
pub fn upload_file(file: &Path, url: &str, options: &RemoteOptions) -> std::io::Result<()> {
    upload::upload(url, options, file, None)
        .map(drop)
        .map_err(|e| match e {
            upload::UploadError::Failed(e) => e,
            upload::UploadError::Conflict => Error::other("the server refused the write (412)"),
        })
}

/// What reading an object cost: requests made, bytes fetched, and what the
/// cache answered instead.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct RemoteStats {
    /// Requests made (HEAD and GET, retries included).
    pub requests: u64,
    /// Bytes the answers carried.
    pub bytes_fetched: u64,
    /// Bytes read from the local cache instead.
    pub cache_hit_bytes: u64,
    /// Requests made again after a failure.
    pub retries: u64,
    /// Requests that timed out (each also a retry or a failure).
    pub timeouts: u64,
    /// Requests that failed after their retries.
    pub failed_requests: u64,
    /// Cached blocks dropped for a failed checksum (then fetched again).
    pub cache_damaged_blocks: u64,
}

#[derive(Debug, Default)]
struct Counters {
    requests: AtomicU64,
    bytes_fetched: AtomicU64,
    cache_hit_bytes: AtomicU64,
    retries: AtomicU64,
    timeouts: AtomicU64,
    failed_requests: AtomicU64,
    cache_damaged_blocks: AtomicU64,
}

fn add(counter: &AtomicU64, n: u64) {
    counter.fetch_add(n, Ordering::Relaxed);
}

/// How an object is addressed.
#[derive(Debug)]
enum Locator {
    /// Through the S3 API, requests signed when there are credentials.
    S3 {
        bucket: Box<Bucket>,
        key: String,
        credentials: Option<Credentials>,
    },
    /// A plain web address.
    Http(String),
}

impl Locator {
    fn parse(url: &str, options: &RemoteOptions) -> std::io::Result<Self> {
        let invalid = |why: &str| Error::new(ErrorKind::InvalidInput, why.to_owned());
        let Some(rest) = url.strip_prefix("s3://") else {
            return Ok(Locator::Http(url.to_owned()));
        };
        let (bucket, key) = rest
            .split_once('/')
            .filter(|(b, k)| !b.is_empty() && !k.is_empty())
            .ok_or_else(|| invalid("give s3://bucket/key"))?;
        let endpoint = options
            .endpoint
            .clone()
            .unwrap_or_else(|| format!("https://s3.{}.amazonaws.com", options.region));
        let endpoint = endpoint
            .parse()
            .map_err(|e| invalid(&format!("endpoint {endpoint:?}: {e}")))?;
        let bucket = Box::new(
            Bucket::new(
                endpoint,
                UrlStyle::Path,
                bucket.to_owned(),
                options.region.clone(),
            )
            .map_err(|e| invalid(&format!("bucket {bucket:?}: {e}")))?,
        );
        Ok(Locator::S3 {
            bucket,
            key: key.to_owned(),
            credentials: options
                .credentials
                .as_ref()
                .map(|(k, s)| Credentials::new(k.clone(), s.clone())),
        })
    }

    /// The address of a HEAD (`head`) or a GET request for the object,
    /// signed for S3 when there are credentials.
    fn url(&self, head: bool) -> String {
        match self {
            Locator::S3 {
                bucket,
                key,
                credentials,
            } => {
                let c = credentials.as_ref();
                match head {
                    true => bucket.head_object(c, key).sign(REQUEST_TTL),
                    false => bucket.get_object(c, key).sign(REQUEST_TTL),
                }
                .into()
            }
            Locator::Http(url) => url.clone(),
        }
    }
}

fn agent() -> ureq::Agent {
    ureq::AgentBuilder::new()
        .timeout_connect(CONNECT_TIMEOUT)
        .timeout_read(READ_TIMEOUT)
        .timeout(REQUEST_TIMEOUT)
        .build()
}

/// One object, read by ranges through the cache.
#[derive(Debug)]
pub(crate) struct RemoteObject {
    agent: ureq::Agent,
    locator: Locator,
    len: u64,
    /// The version read: the ETag the server gave (every range request and
    /// a conditional put ask for it).
    etag: Option<String>,
    cache: Option<BlockCache>,
    counters: Counters,
    /// How it was reached: a rewrite of the store goes the same way.
    options: RemoteOptions,
}

impl RemoteObject {
    /// Opens `url`: its length and version, from a HEAD request.
    pub fn open(url: &str, options: &RemoteOptions) -> std::io::Result<Self> {
        let mut object = Self {
            agent: agent(),
            locator: Locator::parse(url, options)?,
            len: 0,
            etag: None,
            cache: None,
            counters: Counters::default(),
            options: options.clone(),
        };
        let head = object.call(|| object.agent.head(&object.locator.url(true)))?;
        object.len = head
            .header("content-length")
            .and_then(|v| v.parse().ok())
            .ok_or_else(|| Error::other("the server gave no length for the object"))?;
        object.etag = head.header("etag").map(str::to_owned);
        // The cache's key names the version: without one there is no telling
        // a replaced object from the one cached, and such an object is not
        // cached.
        let version = object
            .etag
            .as_deref()
            .or_else(|| head.header("last-modified"))
            .map(str::to_owned);
        if let (Some(dir), Some(version)) = (&options.cache_dir, version)
            && options.cache_budget > 0
        {
            object.cache = Some(BlockCache::open(
                dir,
                options.cache_budget,
                &format!("{url}\n{version}\n{}", object.len),
            )?);
        }
        Ok(object)
    }

    /// How it was reached.
    pub fn options(&self) -> &RemoteOptions {
        &self.options
    }

    /// The version read (the ETag), for a conditional put over it.
    pub fn version(&self) -> Option<&str> {
        self.etag.as_deref()
    }

    /// The counters so far.
    pub fn stats(&self) -> RemoteStats {
        let c = &self.counters;
        let get = |a: &AtomicU64| a.load(Ordering::Relaxed);
        RemoteStats {
            requests: get(&c.requests),
            bytes_fetched: get(&c.bytes_fetched),
            cache_hit_bytes: get(&c.cache_hit_bytes),
            retries: get(&c.retries),
            timeouts: get(&c.timeouts),
            failed_requests: get(&c.failed_requests),
            cache_damaged_blocks: get(&c.cache_damaged_blocks),
        }
    }

    /// Makes the request `make` builds, with [`retrying`].
    fn call(&self, make: impl Fn() -> ureq::Request) -> std::io::Result<ureq::Response> {
        retrying(&self.counters, || boxed(make().call())).map_err(|e| http_error(*e))
    }

    /// Bytes `offset..offset + len` from the server (no cache).
    fn fetch(&self, offset: u64, len: u64) -> std::io::Result<Vec<u8>> {
        if len == 0 {
            return Ok(Vec::new());
        }
        // A body cut short (the server gone mid-answer) is tried again as a
        // failed request is; what is left after the tries is a network
        // error (`ConnectionAborted`), never a short file.
        let cut = |e: &Fetch| matches!(e, Fetch::Cut(_));
        with_retries(&self.counters, || self.fetch_once(offset, len), cut).map_err(|e| match e {
            Fetch::Cut(why) => {
                add(&self.counters.failed_requests, 1);
                Error::new(ErrorKind::ConnectionAborted, why)
            }
            Fetch::Failed(e) => e,
        })
    }

    /// One range request for `offset..offset + len`, checked: a 206 for
    /// that range of this version of the object, and exactly `len` bytes.
    fn fetch_once(&self, offset: u64, len: u64) -> Result<Vec<u8>, Fetch> {
        let last = offset + len - 1;
        let range = format!("bytes={offset}-{last}");
        let response = self
            .call(|| {
                let get = self
                    .agent
                    .get(&self.locator.url(false))
                    .set("Range", &range);
                // Bytes of another version of the object never come back.
                match &self.etag {
                    Some(etag) => get.set("If-Match", etag),
                    None => get,
                }
            })
            .map_err(Fetch::Failed)?;
        if response.status() != 206 {
            return Err(Fetch::Failed(Error::other(format!(
                "the server answered a range request with status {} (not 206)",
                response.status()
            ))));
        }
        let answered = response.header("content-range").unwrap_or_default();
        if !answered.starts_with(&format!("bytes {offset}-{last}/")) {
            return Err(Fetch::Failed(Error::other(format!(
                "asked for bytes {offset}-{last}, the server answered {answered:?}"
            ))));
        }
        let mut bytes = Vec::new();
        let read = response.into_reader().take(len + 1).read_to_end(&mut bytes);
        add(&self.counters.bytes_fetched, bytes.len() as u64);
        match read {
            Err(e) => Err(Fetch::Cut(format!(
                "the answer broke off after {} of {len} bytes at {offset}: {e}",
                bytes.len()
            ))),
            Ok(_) if bytes.len() as u64 != len => Err(Fetch::Cut(format!(
                "asked for {len} bytes at {offset}, got {}",
                bytes.len()
            ))),
            Ok(_) => Ok(bytes),
        }
    }

    /// Bytes `offset..offset + len` (within the object): from the cache's
    /// blocks where it has them, the rest fetched a run of blocks at a time.
    fn read(&self, offset: u64, len: u64) -> std::io::Result<Vec<u8>> {
        let Some(cache) = &self.cache else {
            return self.fetch(offset, len);
        };
        if len == 0 {
            return Ok(Vec::new());
        }
        let first = offset / BLOCK_BYTES;
        let last = (offset + len - 1) / BLOCK_BYTES;
        let block_len = |b: u64| BLOCK_BYTES.min(self.len - b * BLOCK_BYTES);
        let look = |b: u64| {
            let hit = cache.get(b, block_len(b));
            match &hit {
                Ok(Some(bytes)) => add(&self.counters.cache_hit_bytes, bytes.len() as u64),
                Err(cache::Damaged) => add(&self.counters.cache_damaged_blocks, 1),
                Ok(None) => {}
            }
            hit.ok().flatten()
        };
        let mut blocks: Vec<Option<Vec<u8>>> = (first..=last).map(look).collect();
        let missing = || (first..=last).filter(|&b| blocks[(b - first) as usize].is_none());
        let _claim = cache.claim(missing().collect());
        // Fetched meanwhile by another reader?
        for b in missing().collect::<Vec<_>>() {
            blocks[(b - first) as usize] = look(b);
        }
        // Runs of missing blocks, each cut into requests of at most
        // MAX_REQUEST_BYTES.
        let per_request = MAX_REQUEST_BYTES / BLOCK_BYTES;
        let mut requests: Vec<(u64, u64)> = Vec::new();
        let mut b = first;
        while b <= last {
            if blocks[(b - first) as usize].is_some() {
                b += 1;
                continue;
            }
            let start = b;
            while b <= last && blocks[(b - first) as usize].is_none() && b - start < per_request {
                b += 1;
            }
            requests.push((start, b));
        }
        let fetch = |&(a, b): &(u64, u64)| {
            let from = a * BLOCK_BYTES;
            self.fetch(from, (b * BLOCK_BYTES).min(self.len) - from)
        };
        in_flight(&requests, fetch, |&(a, _), bytes: Vec<u8>| {
            for (i, block) in bytes.chunks(BLOCK_BYTES as usize).enumerate() {
                let index = a + i as u64;
                cache.put(index, block);
                blocks[(index - first) as usize] = Some(block.to_vec());
            }
            Ok::<_, Error>(())
        })?;
        let mut out = Vec::new();
        let mut at = offset;
        for (i, block) in blocks.into_iter().enumerate() {
            let block = block.ok_or_else(|| Error::other("a block was not fetched"))?;
            let base = (first + i as u64) * BLOCK_BYTES;
            let from = (at - base) as usize;
            let to = ((offset + len).min(base + block.len() as u64) - base) as usize;
            out.extend_from_slice(&block[from..to]);
            at = base + to as u64;
        }
        Ok(out)
    }
}

/// Runs `attempt`, and again [`RETRIES`] times at most (after 0.1 s, then
/// 0.4 s) while its error is one `again` says is worth another try, each
/// retry counted.
fn with_retries<T, E>(
    c: &Counters,
    attempt: impl Fn() -> Result<T, E>,
    again: impl Fn(&E) -> bool,
) -> Result<T, E> {
    let mut tries = 0;
    loop {
        match attempt() {
            Err(e) if again(&e) && tries < RETRIES => {
                add(&c.retries, 1);
                std::thread::sleep(Duration::from_millis(100 << (2 * tries)));
                tries += 1;
            }
            result => return result,
        }
    }
}

/// Makes a request by `attempt`, retrying failures of the network and of
/// the server (5xx, 429) [`RETRIES`] times, counting each try.
fn retrying(
    c: &Counters,
    attempt: impl Fn() -> Result<ureq::Response, Box<ureq::Error>>,
) -> Result<ureq::Response, Box<ureq::Error>> {
    let request = || {
        add(&c.requests, 1);
        attempt()
    };
    let retryable = |error: &ureq::Error| match error {
        ureq::Error::Status(code, _) => *code >= 500 || *code == 429,
        ureq::Error::Transport(t) => {
            if is_timeout(t) {
                add(&c.timeouts, 1);
            }
            true
        }
    };
    with_retries(c, request, |e| retryable(e)).inspect_err(|_| add(&c.failed_requests, 1))
}

/// Runs `work` on every item, [`IN_FLIGHT`] at once on threads of their
/// own (the work waits on the network, not on a core), and hands each
/// result to `done` in the items' order, a batch at a time: the first error
/// ends it after its batch.
fn in_flight<T: Sync, R: Send, E: Send + From<Error>>(
    items: &[T],
    work: impl Fn(&T) -> Result<R, E> + Sync,
    mut done: impl FnMut(&T, R) -> Result<(), E>,
) -> Result<(), E> {
    for batch in items.chunks(IN_FLIGHT) {
        let results: Vec<Result<R, E>> = std::thread::scope(|s| {
            let handles: Vec<_> = batch.iter().map(|item| s.spawn(|| work(item))).collect();
            handles
                .into_iter()
                .map(|h| {
                    h.join()
                        .unwrap_or_else(|_| Err(Error::other("a request's thread panicked").into()))
                })
                .collect()
        });
        for (item, result) in batch.iter().zip(results) {
            done(item, result?)?;
        }
    }
    Ok(())
}

/// A request's result with its (large) error boxed.
fn boxed(r: Result<ureq::Response, ureq::Error>) -> Result<ureq::Response, Box<ureq::Error>> {
    r.map_err(Box::new)
}

/// Why a range request gave no bytes.
enum Fetch {
    /// The answer broke off or came short: worth another try.
    Cut(String),
    /// Anything else (its retries, if any, made).
    Failed(Error),
}

/// Whether a transport error is a timeout.
fn is_timeout(t: &ureq::Transport) -> bool {
    std::error::Error::source(t)
        .and_then(|e| e.downcast_ref::<Error>())
        .is_some_and(|e| matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock))
        || t.to_string().contains("timed out")
}

/// A failed request as an I/O error: a missing object is `NotFound`, and
/// its message says what the server answered.
fn http_error(e: ureq::Error) -> Error {
    match e {
        ureq::Error::Status(404, _) => Error::new(ErrorKind::NotFound, "no such object (404)"),
        ureq::Error::Status(412, _) => Error::other(
            "the object changed since it was opened (412): open it again to read the new version",
        ),
        ureq::Error::Status(code, r) => {
            let status = r.status_text().to_owned();
            // S3 says why in its XML body: <Code> and <Message>.
            let body = r.into_string().unwrap_or_default();
            let tag = |t: &str| {
                let open = format!("<{t}>");
                let from = body.find(&open)? + open.len();
                let to = from + body[from..].find('<')?;
                Some(body[from..to].chars().take(200).collect::<String>())
            };
            match (tag("Code"), tag("Message")) {
                (Some(c), Some(m)) => Error::other(format!("the server answered {code} {c}: {m}")),
                _ => Error::other(format!("the server answered {code} {status}")),
            }
        }
        // Its Display names the URL, signature and all: kind and cause only.
        ureq::Error::Transport(t) => {
            let cause = std::error::Error::source(&t).map(ToString::to_string);
            let message = t.message().map(str::to_owned).or(cause);
            Error::other(match message {
                Some(m) => format!("{}: {m}", t.kind()),
                None => t.kind().to_string(),
            })
        }
    }
}

impl ReadAt for RemoteObject {
    fn len(&self) -> std::io::Result<u64> {
        Ok(self.len)
    }

    fn read_exact_at(&self, offset: u64, len: u64) -> std::io::Result<Vec<u8>> {
        if len > MAX_READ_BYTES {
            // The length is the server's word: no allocation on it alone.
            return Err(Error::new(
                ErrorKind::InvalidData,
                format!("a read of {len} bytes, more than the {MAX_READ_BYTES} one read takes"),
            ));
        }
        if offset.checked_add(len).is_none_or(|end| end > self.len) {
            return Err(Error::new(
                ErrorKind::UnexpectedEof,
                "past the object's end",
            ));
        }
        self.read(offset, len)
    }

    fn read_at_most(&self, offset: u64, len: u64) -> std::io::Result<Vec<u8>> {
        if offset >= self.len {
            return Ok(Vec::new());
        }
        self.read_exact_at(offset, len.min(self.len - offset))
    }

    fn read_into(&self, offset: u64, buf: &mut [u8]) -> std::io::Result<()> {
        buf.copy_from_slice(&self.read_exact_at(offset, buf.len() as u64)?);
        Ok(())
    }
}
