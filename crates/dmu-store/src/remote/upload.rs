//! Putting a finished store (a local file) on object storage: one PUT up to
//! one part, else a multipart upload of [`PART_BYTES`] parts,
//! [`super::IN_FLIGHT`] at a time. Either may be conditional on the version
//! the store was read at (`If-Match`): S3 and SeaweedFS then refuse it with
//! 412 when another writer got there first, and nothing is overwritten.

use std::io::{Error, ErrorKind};
use std::os::unix::fs::FileExt as _;
use std::path::Path;

use rusty_s3::S3Action;
use rusty_s3::actions::{
    CompleteMultipartUpload, CompleteMultipartUploadResponse, CreateMultipartUpload,
};

use super::{
    Counters, Locator, REQUEST_TTL, RemoteOptions, agent, boxed, http_error, in_flight, retrying,
};

/// The size of each part by default ([`RemoteOptions::part_bytes`]); a
/// store of one part is put whole.
pub const PART_BYTES: u64 = 16 << 20;
/// The least part S3 takes (but for the last).
const LEAST_PART_BYTES: u64 = 5 << 20;

/// Why an upload did not happen.
#[derive(Debug)]
pub(crate) enum UploadError {
    /// The object is no longer at the version the write was conditional on.
    Conflict,
    /// Anything else.
    Failed(Error),
}

impl From<Error> for UploadError {
    fn from(e: Error) -> Self {
        UploadError::Failed(e)
    }
}

/// A failed request: 412 is the conflict, anything else an I/O error.
fn refused(e: Box<ureq::Error>) -> UploadError {
    match *e {
        ureq::Error::Status(412, _) => UploadError::Conflict,
        e => UploadError::Failed(http_error(e)),
    }
}

/// Puts `file` as the object `url` (`s3://` only), over `version` when it
/// is given (`If-Match`: refused as [`UploadError::Conflict`] when the
/// object has changed since); the new object's version (ETag), when the
/// server says.
pub(crate) fn upload(
    url: &str,
    options: &RemoteOptions,
    file: &Path,
    version: Option<&str>,
) -> Result<Option<String>, UploadError> {
    let Locator::S3 {
        bucket,
        key,
        credentials,
    } = Locator::parse(url, options)?
    else {
        return Err(Error::new(
            ErrorKind::Unsupported,
            "stores are written to s3:// addresses only, not to http(s)",
        )
        .into());
    };
    let credentials = credentials.as_ref();
    let agent = agent();
    let counters = Counters::default();
    let with_condition = |request: ureq::Request| match version {
        Some(v) => request.set("If-Match", v),
        None => request,
    };
    let source = std::fs::File::open(file)?;
    let len = source.metadata()?.len();
    let read = |offset: u64, n: u64| -> std::io::Result<Vec<u8>> {
        let mut buf = vec![0; usize::try_from(n).map_err(Error::other)?];
        source.read_exact_at(&mut buf, offset)?;
        Ok(buf)
    };
    let part_bytes = options
        .part_bytes
        .unwrap_or(PART_BYTES)
        .max(LEAST_PART_BYTES);
    if len <= part_bytes {
        let body = read(0, len)?;
        let put = bucket.put_object(credentials, &key).sign(REQUEST_TTL);
        let answer = retrying(&counters, || {
            boxed(with_condition(agent.put(put.as_str())).send_bytes(&body))
        })
        .map_err(refused)?;
        return Ok(answer.header("etag").map(str::to_owned));
    }
    // Before hundreds of megabytes go up: has someone saved since?
    if let Some(v) = version {
        let head = bucket.head_object(credentials, &key).sign(REQUEST_TTL);
        let now =
            retrying(&counters, || boxed(agent.head(head.as_str()).call())).map_err(refused)?;
        if now.header("etag") != Some(v) {
            return Err(UploadError::Conflict);
        }
    }
    let create = bucket
        .create_multipart_upload(credentials, &key)
        .sign(REQUEST_TTL);
    let answer = retrying(&counters, || boxed(agent.post(create.as_str()).call()))
        .map_err(refused)?
        .into_string()?;
    let created = CreateMultipartUpload::parse_response(&answer)
        .map_err(|e| Error::other(format!("the server's answer to a multipart upload: {e}")))?;
    let id = created.upload_id();
    let parts = len.div_ceil(part_bytes);
    let put_part = |part: u64| -> Result<String, UploadError> {
        let offset = (part - 1) * part_bytes;
        let body = read(offset, part_bytes.min(len - offset))?;
        let number = u16::try_from(part).map_err(|_| Error::other("over 65535 parts"))?;
        let url = bucket
            .upload_part(credentials, &key, number, id)
            .sign(REQUEST_TTL);
        let answer = retrying(&counters, || {
            boxed(agent.put(url.as_str()).send_bytes(&body))
        })
        .map_err(refused)?;
        answer
            .header("etag")
            .map(str::to_owned)
            .ok_or_else(|| Error::other(format!("the server gave no ETag for part {part}")).into())
    };
    let result = (|| {
        let mut etags = Vec::new();
        let numbers: Vec<u64> = (1..=parts).collect();
        in_flight(
            &numbers,
            |&p| put_part(p),
            |_, etag| {
                etags.push(etag);
                Ok(())
            },
        )?;
        let complete = || {
            CompleteMultipartUpload::new(
                &bucket,
                credentials,
                &key,
                id,
                etags.iter().map(String::as_str),
            )
        };
        let url = complete().sign(REQUEST_TTL);
        let body = complete().body();
        let answer = retrying(&counters, || {
            boxed(with_condition(agent.post(url.as_str())).send_string(&body))
        })
        .map_err(refused)?
        .into_string()?;
        // S3 may answer 200 and still have failed: the body says.
        if !answer.contains("<Error>") {
            let done = CompleteMultipartUploadResponse::parse(&answer).ok();
            return Ok(done.map(|d| d.etag().to_owned()));
        }
        Err(if answer.contains("PreconditionFailed") {
            UploadError::Conflict
        } else {
            Error::other(format!(
                "the server did not complete the upload: {}",
                answer.lines().next().unwrap_or_default()
            ))
            .into()
        })
    })();
    if result.is_err() {
        // Parts left behind cost storage; a failed abort changes nothing.
        let abort = bucket
            .abort_multipart_upload(credentials, &key, id)
            .sign(REQUEST_TTL);
        let _ = retrying(&counters, || boxed(agent.delete(abort.as_str()).call()));
    }
    result
}
