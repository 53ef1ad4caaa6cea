//! `mktree serve OUT/`: the tileset `export-3dtiles` wrote to OUT/, and a
//! page that shows it (viewer/index.html: three.js and 3DTilesRendererJS,
//! installed by viewer/install.sh), over HTTP/1.1 on 127.0.0.1 only.
//!
//! hyper on a two-thread tokio runtime serves the connections and
//! tower-http's `ServeFile` answers each file: it streams the file in
//! chunks of [`CHUNK`] bytes, answers range requests (`206`, `416`) and
//! conditional ones (`304`). Nothing reads a whole file into memory.
//!
//! Memory bound: at most [`MAX_CONNECTIONS`] connections are served at
//! once (the next waits in the kernel's accept queue), each holding at most
//! one chunk and hyper's buffers (head bytes at most [`MAX_HEAD`]), and at
//! most [`BLOCKING_THREADS`] threads read files. So the peak resident
//! memory stays under [`MEMORY_BOUND`] whatever the files' sizes
//! (cli/tests/serve_limits.rs measures it with a 3 GiB file). A client that
//! sends no complete head within [`HEAD_TIMEOUT`] is dropped, so silent
//! clients cannot hold the connections for ever.
//!
//! Routes: `/` is the page, `/tiles/...` the tileset's files, `/vendor/...`
//! the page's JavaScript packages. Only plain relative paths are served: a
//! segment that is empty, starts with a dot or holds anything but letters,
//! digits, `-`, `_` and `.` is not found. A path whose real location
//! (symbolic links resolved) is outside its folder is not found either, so
//! no request leaves the two folders.

use std::convert::Infallible;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result, bail};
use bytes::Bytes;
use http::{HeaderValue, Method, Request, Response, StatusCode, header};
use http_body_util::combinators::UnsyncBoxBody;
use http_body_util::{BodyExt, Full};
use hyper_util::rt::{TokioIo, TokioTimer};
use tower::ServiceExt;
use tower_http::services::ServeFile;

/// The page, built into the binary.
const PAGE: &str = include_str!("../../../viewer/index.html");

/// Where viewer/install.sh puts the page's packages in a checkout.
const VENDOR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../viewer/node_modules");

/// Connections served at once; more wait in the accept queue. Above the
/// 300 concurrent clients issue 39 asks for, well above a browser's six.
pub const MAX_CONNECTIONS: usize = 512;

/// Bytes of a file read and sent at a time.
pub const CHUNK: usize = 64 * 1024;

/// The most bytes hyper buffers of a request's head (request line and headers).
pub const MAX_HEAD: usize = 64 * 1024;

/// Threads that read files (tokio's blocking pool).
pub const BLOCKING_THREADS: usize = 8;

/// How long a connection may take to send a request's head.
pub const HEAD_TIMEOUT: Duration = Duration::from_secs(10);

/// The stated bound on the server's peak resident memory: the program and
/// runtime (about 10 MiB) plus, per connection, one chunk and a head
/// buffer (512 x 128 KiB = 64 MiB).
pub const MEMORY_BOUND: u64 = 96 << 20;

/// A response body: the page or a message from memory, or a file streamed.
type Body = UnsyncBoxBody<Bytes, std::io::Error>;

/// The two folders served, as their real paths.
struct Roots {
    tiles: PathBuf,
    vendor: PathBuf,
}

pub fn run(tiles: &Path, port: u16, vendor: Option<&Path>) -> Result<()> {
    if !tiles.join("tileset.json").is_file() {
        bail!(
            "{} holds no tileset.json: write one with `mktree export-3dtiles FILE.mkt {}`",
            tiles.display(),
            tiles.display()
        );
    }
    let vendor = vendor.map_or_else(|| PathBuf::from(VENDOR), Path::to_path_buf);
    if !vendor.join("three").is_dir() || !vendor.join("3d-tiles-renderer").is_dir() {
        bail!(
            "{} lacks three and 3d-tiles-renderer: run viewer/install.sh, or pass --vendor DIR",
            vendor.display()
        );
    }
    let roots = Arc::new(Roots {
        tiles: tiles.canonicalize().with_context(|| tiles.display().to_string())?,
        vendor: vendor.canonicalize().with_context(|| vendor.display().to_string())?,
    });
    let listener =
        std::net::TcpListener::bind(("127.0.0.1", port)).with_context(|| format!("127.0.0.1:{port}"))?;
    let port = listener.local_addr().context("the bound address")?.port();
    listener.set_nonblocking(true).context("the listening socket")?;
    // A script waiting for the server reads this line.
    println!("serving {} at http://127.0.0.1:{port}/", tiles.display());
    std::io::stdout().flush().context("stdout")?;
    eprintln!(
        "mktree: at most {MAX_CONNECTIONS} connections at once, files sent in {} KiB chunks, memory under {} MiB",
        CHUNK >> 10,
        MEMORY_BOUND >> 20
    );
    ignore_broken_pipes();
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .max_blocking_threads(BLOCKING_THREADS)
        .enable_all()
        .build()
        .context("starting the server's runtime")?;
    runtime.block_on(accept_loop(listener, roots))
}

/// main() gives SIGPIPE its default action, which ends the process, so
/// that `mktree dump | head` ends quietly. A server must not end when a
/// client closes mid-download: writing to that socket then fails with
/// EPIPE instead, and hyper drops the connection.
#[cfg(unix)]
fn ignore_broken_pipes() {
    // SAFETY: called before the runtime's threads start, with no other
    // thread changing signal actions; SIG_IGN is a valid action for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_IGN);
    }
}

#[cfg(not(unix))]
fn ignore_broken_pipes() {}

/// Accepts connections, at most [`MAX_CONNECTIONS`] served at once.
async fn accept_loop(listener: std::net::TcpListener, roots: Arc<Roots>) -> Result<()> {
    let listener = tokio::net::TcpListener::from_std(listener).context("the listening socket")?;
    let slots = Arc::new(tokio::sync::Semaphore::new(MAX_CONNECTIONS));
    loop {
        // Take the slot before accepting, so that clients beyond the bound
        // wait in the kernel's queue and cost this process nothing.
        let slot = slots.clone().acquire_owned().await.context("the connection slots")?;
        let stream = match listener.accept().await {
            Ok((stream, _)) => stream,
            // Out of descriptors, or a connection reset before it was
            // accepted: neither ends the server. Pause so a persistent
            // error does not spin.
            Err(_) => {
                tokio::time::sleep(Duration::from_millis(50)).await;
                continue;
            }
        };
        // hyper writes a response's head and its body's chunks apart; with
        // Nagle's algorithm the body waits for the head's ACK, which a
        // client delays by up to 40 ms: a range request costs that much
        // more (seen by `bench-remote`). A failure only leaves the delay.
        let _ = stream.set_nodelay(true);
        let roots = roots.clone();
        tokio::spawn(async move {
            let service = hyper::service::service_fn(move |req| answer(req, roots.clone()));
            // A client that went away, or sent no head in time, is no error of the server's.
            let _ = hyper::server::conn::http1::Builder::new()
                .timer(TokioTimer::new())
                .header_read_timeout(HEAD_TIMEOUT)
                .max_buf_size(MAX_HEAD)
                .serve_connection(TokioIo::new(stream), service)
                .await;
            drop(slot);
        });
    }
}

/// Answers one request.
async fn answer<B>(req: Request<B>, roots: Arc<Roots>) -> Result<Response<Body>, Infallible>
where
    B: Send + 'static,
{
    if req.method() != Method::GET && req.method() != Method::HEAD {
        return Ok(message(StatusCode::METHOD_NOT_ALLOWED, "only GET and HEAD"));
    }
    let path = req.uri().path();
    if path == "/" || path == "/index.html" {
        let mut r = Response::new(full(if req.method() == Method::HEAD { "" } else { PAGE }));
        r.headers_mut().insert(header::CONTENT_TYPE, HeaderValue::from_static("text/html; charset=utf-8"));
        return Ok(r);
    }
    let file = path
        .strip_prefix("/tiles/")
        .map(|rest| (&roots.tiles, rest))
        .or_else(|| path.strip_prefix("/vendor/").map(|rest| (&roots.vendor, rest)))
        .and_then(|(root, rest)| file_under(root, rest));
    let Some(file) = file else {
        return Ok(message(StatusCode::NOT_FOUND, "not found"));
    };
    let kind = content_type(&file);
    let Ok(mut r) = ServeFile::new(&file).with_buf_chunk_size(CHUNK).oneshot(req).await;
    if r.status().is_success() {
        r.headers_mut().insert(header::CONTENT_TYPE, HeaderValue::from_static(kind));
    }
    Ok(r.map(|b| b.map_err(std::io::Error::other).boxed_unsync()))
}

/// A short plain-text answer.
fn message(status: StatusCode, text: &'static str) -> Response<Body> {
    let mut r = Response::new(full(text));
    *r.status_mut() = status;
    r.headers_mut().insert(header::CONTENT_TYPE, HeaderValue::from_static("text/plain"));
    r
}

fn full(text: &'static str) -> Body {
    Full::new(Bytes::from_static(text.as_bytes())).map_err(|never| match never {}).boxed_unsync()
}

/// The real path of `root/rest` if every segment of `rest` is a plain name
/// (see the module's note) and the file it names, symbolic links followed,
/// is a regular file inside `root` (itself a real path).
fn file_under(root: &Path, rest: &str) -> Option<PathBuf> {
    let plain = |seg: &str| {
        !seg.is_empty()
            && !seg.starts_with('.')
            && seg.bytes().all(|b| b.is_ascii_alphanumeric() || matches!(b, b'-' | b'_' | b'.'))
    };
    let mut path = root.to_path_buf();
    for seg in rest.split('/') {
        if !plain(seg) {
            return None;
        }
        path.push(seg);
    }
    // The real path is served, not `path`: a link swapped in after this
    // check cannot redirect the read.
    let real = path.canonicalize().ok()?;
    (real.starts_with(root) && real.is_file()).then_some(real)
}

fn content_type(file: &Path) -> &'static str {
    match file.extension().and_then(|e| e.to_str()) {
        Some("html") => "text/html; charset=utf-8",
        Some("js" | "mjs") => "text/javascript",
        Some("json" | "map") => "application/json",
        Some("glb") => "model/gltf-binary",
        Some("wasm") => "application/wasm",
        _ => "application/octet-stream",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn root() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).canonicalize().unwrap()
    }

    #[test]
    fn only_plain_relative_paths_are_served() {
        let root = root();
        assert!(file_under(&root, "Cargo.toml").is_some());
        assert!(file_under(&root, "src/main.rs").is_some());
        for bad in [
            "../Cargo.toml",
            "src/../Cargo.toml",
            "/etc/passwd",
            "src//main.rs",
            ".git/config",
            "src/%2e%2e/x",
            "src",
            "",
        ] {
            assert_eq!(file_under(&root, bad), None, "{bad}");
        }
    }

    #[cfg(unix)]
    #[test]
    fn links_are_served_only_when_they_stay_inside_the_folder() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().canonicalize().unwrap();
        std::fs::write(root.join("a.json"), "{}").unwrap();
        std::os::unix::fs::symlink(root.join("a.json"), root.join("inside.json")).unwrap();
        std::os::unix::fs::symlink("/etc/passwd", root.join("passwd")).unwrap();
        std::os::unix::fs::symlink("/etc", root.join("etc")).unwrap();
        assert_eq!(file_under(&root, "inside.json"), Some(root.join("a.json")));
        assert_eq!(file_under(&root, "passwd"), None);
        assert_eq!(file_under(&root, "etc/passwd"), None);
    }
}
