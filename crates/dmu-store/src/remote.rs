//! Stores on object storage: `s3://bucket/key` on S3 or a server that speaks
//! its API (SeaweedFS, MinIO), read a byte range at a time with HTTP range
//! requests. A store read this way is checked exactly as a local one: every
//! segment against its checksum, every count against the bytes that hold it.
//! Reading only: saving edits or far fields to object storage is refused.
//!
//! Where and as whom (`RemoteOptions::from_env`, the AWS variables):
//! `AWS_ENDPOINT_URL` (else AWS's own endpoint for the region),
//! `AWS_REGION` or `AWS_DEFAULT_REGION` (default `us-east-1`), and
//! `AWS_ACCESS_KEY_ID` with `AWS_SECRET_ACCESS_KEY` (signed requests; none:
//! anonymous).

use std::io::{Error, ErrorKind, Read as _};
use std::path::Path;
use std::time::Duration;

use rusty_s3::{Bucket, Credentials, S3Action, UrlStyle};

use crate::format::ReadAt;

/// How long a signed request stays valid, and how long a request may take.
const REQUEST_TTL: Duration = Duration::from_secs(300);
/// How long connecting and each read may take before the request fails:
/// a server that stops answering is an error, never a hang.
const TIMEOUT: Duration = Duration::from_secs(30);

/// Where object storage is and who asks.
#[derive(Clone, Debug, Default)]
pub struct RemoteOptions {
    /// The server, e.g. `http://127.0.0.1:8333`; `None` for AWS.
    pub endpoint: Option<String>,
    /// The region (AWS's, or any name the server accepts).
    pub region: String,
    /// Access key and secret; `None` for anonymous requests.
    pub credentials: Option<(String, String)>,
}

impl RemoteOptions {
    /// From the AWS variables (see the module's documentation).
    pub fn from_env() -> Self {
        let var = |k: &str| std::env::var(k).ok().filter(|v| !v.is_empty());
        Self {
            endpoint: var("AWS_ENDPOINT_URL"),
            region: var("AWS_REGION")
                .or_else(|| var("AWS_DEFAULT_REGION"))
                .unwrap_or_else(|| "us-east-1".into()),
            credentials: var("AWS_ACCESS_KEY_ID").zip(var("AWS_SECRET_ACCESS_KEY")),
        }
    }
}

/// Whether `path` names an object (`s3://bucket/key`) rather than a file.
pub fn is_remote(path: &Path) -> bool {
    path.to_str().is_some_and(|s| s.starts_with("s3://"))
}

/// One object, read by ranges.
#[derive(Debug)]
pub(crate) struct S3Object {
    agent: ureq::Agent,
    bucket: Bucket,
    key: String,
    credentials: Option<Credentials>,
    len: u64,
}

impl S3Object {
    /// Opens `s3://bucket/key`: its length, from a HEAD request.
    pub fn open(url: &str, options: &RemoteOptions) -> std::io::Result<Self> {
        let invalid = |why: &str| Error::new(ErrorKind::InvalidInput, why.to_owned());
        let rest = url
            .strip_prefix("s3://")
            .ok_or_else(|| invalid("not an s3:// address"))?;
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
        let bucket = Bucket::new(
            endpoint,
            UrlStyle::Path,
            bucket.to_owned(),
            options.region.clone(),
        )
        .map_err(|e| invalid(&format!("bucket {bucket:?}: {e}")))?;
        let agent = ureq::AgentBuilder::new()
            .timeout_connect(TIMEOUT)
            .timeout_read(TIMEOUT)
            .build();
        let mut object = Self {
            agent,
            bucket,
            key: key.to_owned(),
            credentials: options
                .credentials
                .as_ref()
                .map(|(k, s)| Credentials::new(k.clone(), s.clone())),
            len: 0,
        };
        let url = object
            .bucket
            .head_object(object.credentials.as_ref(), &object.key)
            .sign(REQUEST_TTL);
        let head = object.agent.head(url.as_str()).call().map_err(http_error)?;
        object.len = head
            .header("content-length")
            .and_then(|v| v.parse().ok())
            .ok_or_else(|| Error::other("the server gave no length for the object"))?;
        Ok(object)
    }

    /// Bytes `offset..offset + len` (within the object).
    fn range(&self, offset: u64, len: u64) -> std::io::Result<Vec<u8>> {
        if len == 0 {
            return Ok(Vec::new());
        }
        let url = self
            .bucket
            .get_object(self.credentials.as_ref(), &self.key)
            .sign(REQUEST_TTL);
        let response = self
            .agent
            .get(url.as_str())
            .set("Range", &format!("bytes={offset}-{}", offset + len - 1))
            .call()
            .map_err(http_error)?;
        if response.status() != 206 {
            return Err(Error::other(format!(
                "the server answered a range request with status {} (not 206)",
                response.status()
            )));
        }
        let mut bytes = Vec::with_capacity(usize::try_from(len).map_err(Error::other)?);
        response
            .into_reader()
            .take(len + 1)
            .read_to_end(&mut bytes)?;
        if bytes.len() as u64 != len {
            return Err(Error::new(
                ErrorKind::UnexpectedEof,
                format!("asked for {len} bytes at {offset}, got {}", bytes.len()),
            ));
        }
        Ok(bytes)
    }
}

/// A failed request as an I/O error: a missing object is `NotFound`, and
/// its message says what the server answered.
fn http_error(e: ureq::Error) -> Error {
    match e {
        ureq::Error::Status(404, _) => Error::new(ErrorKind::NotFound, "no such object (404)"),
        ureq::Error::Status(code, r) => {
            Error::other(format!("the server answered {code} {}", r.status_text()))
        }
        ureq::Error::Transport(t) => Error::other(t.to_string()),
    }
}

impl ReadAt for S3Object {
    fn len(&self) -> std::io::Result<u64> {
        Ok(self.len)
    }

    fn read_exact_at(&self, offset: u64, len: u64) -> std::io::Result<Vec<u8>> {
        if offset.checked_add(len).is_none_or(|end| end > self.len) {
            return Err(Error::new(
                ErrorKind::UnexpectedEof,
                "past the object's end",
            ));
        }
        self.range(offset, len)
    }

    fn read_at_most(&self, offset: u64, len: u64) -> std::io::Result<Vec<u8>> {
        self.range(offset, len.min(self.len.saturating_sub(offset)))
    }

    fn read_into(&self, offset: u64, buf: &mut [u8]) -> std::io::Result<()> {
        buf.copy_from_slice(&self.read_exact_at(offset, buf.len() as u64)?);
        Ok(())
    }
}
