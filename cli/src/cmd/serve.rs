//! `mktree serve OUT/`: the tileset `export-3dtiles` wrote to OUT/, and a
//! page that shows it (viewer/index.html: three.js and 3DTilesRendererJS,
//! installed by viewer/install.sh), over HTTP on 127.0.0.1 only. A plain
//! HTTP/1.1 server of one request per connection (tiny_http's keep-alive
//! left about one page load in eight with tiles that never arrived).
//!
//! Routes: `/` is the page, `/tiles/...` the tileset's files, `/vendor/...`
//! the page's JavaScript packages. Only plain relative paths are served:
//! a segment that is empty, starts with a dot or holds anything but
//! letters, digits, `-`, `_` and `.` is not found, so no request leaves the
//! two folders.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context, Result, bail};

/// The page, built into the binary.
const PAGE: &str = include_str!("../../../viewer/index.html");

/// Where viewer/install.sh puts the page's packages in a checkout.
const VENDOR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../viewer/node_modules");

/// The most bytes of a request's head read (request line and headers).
const MAX_HEAD: u64 = 64 * 1024;

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
    let listener = TcpListener::bind(("127.0.0.1", port)).with_context(|| format!("127.0.0.1:{port}"))?;
    let port = listener.local_addr().context("the bound address")?.port();
    // A script waiting for the server reads this line.
    println!("serving {} at http://127.0.0.1:{port}/", tiles.display());
    std::io::stdout().flush().context("stdout")?;
    // One request per connection, each on its own thread: the browser opens
    // as many as it has requests in flight, and no connection waits on another.
    for stream in listener.incoming().flatten() {
        let (tiles, vendor) = (tiles.to_path_buf(), vendor.clone());
        std::thread::spawn(move || {
            // A client that went away is no error of the server's.
            let _ = handle(stream, &tiles, &vendor);
        });
    }
    Ok(())
}

/// Reads one request from `stream` and answers it, then closes.
fn handle(mut stream: TcpStream, tiles: &Path, vendor: &Path) -> std::io::Result<()> {
    stream.set_read_timeout(Some(Duration::from_secs(30)))?;
    let mut head = BufReader::new((&stream).take(MAX_HEAD));
    let mut request_line = String::new();
    head.read_line(&mut request_line)?;
    // The headers are not needed; read up to the blank line ending them.
    let mut header = String::new();
    while head.read_line(&mut header)? > 0 && !header.trim().is_empty() {
        header.clear();
    }
    let mut words = request_line.split_whitespace();
    let (method, url) = (words.next().unwrap_or_default(), words.next().unwrap_or_default());
    let (status, kind, body) = match method {
        "GET" | "HEAD" => answer(url, tiles, vendor),
        _ => (405, "text/plain", b"only GET and HEAD".to_vec()),
    };
    let reason = match status {
        200 => "OK",
        404 => "Not Found",
        _ => "Method Not Allowed",
    };
    write!(
        stream,
        "HTTP/1.1 {status} {reason}\r\nContent-Type: {kind}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        body.len()
    )?;
    if method != "HEAD" {
        stream.write_all(&body)?;
    }
    stream.flush()
}

/// The status, content type and body answering a GET of `url`.
fn answer(url: &str, tiles: &Path, vendor: &Path) -> (u16, &'static str, Vec<u8>) {
    let path = url.split(['?', '#']).next().unwrap_or_default();
    let found = match path {
        "/" | "/index.html" => Some((PAGE.as_bytes().to_vec(), "text/html; charset=utf-8")),
        _ => path
            .strip_prefix("/tiles/")
            .map(|rest| (tiles, rest))
            .or_else(|| path.strip_prefix("/vendor/").map(|rest| (vendor, rest)))
            .and_then(|(root, rest)| file_under(root, rest))
            .and_then(|file| Some((std::fs::read(&file).ok()?, content_type(&file)))),
    };
    match found {
        Some((bytes, kind)) => (200, kind, bytes),
        None => (404, "text/plain", b"not found".to_vec()),
    }
}

/// `root/rest` if every segment of `rest` is a plain name (see the module's note).
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
    path.is_file().then_some(path)
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

    #[test]
    fn only_plain_relative_paths_are_served() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        assert!(file_under(root, "Cargo.toml").is_some());
        assert!(file_under(root, "src/main.rs").is_some());
        for bad in [
            "../Cargo.toml",
            "src/../Cargo.toml",
            "/etc/passwd",
            "src//main.rs",
            ".git/config",
            "src/%2e%2e/x",
            "",
        ] {
            assert_eq!(file_under(root, bad), None, "{bad}");
        }
    }

    #[test]
    fn the_page_and_missing_files_answer() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        assert_eq!(answer("/", root, root).0, 200);
        assert_eq!(answer("/?error=4", root, root).0, 200);
        assert_eq!(answer("/tiles/Cargo.toml", root, root).0, 200);
        assert_eq!(answer("/tiles/../Cargo.toml", root, root).0, 404);
        assert_eq!(answer("/elsewhere", root, root).0, 404);
    }
}
