//! `mktree serve OUT/`: the tileset `export-3dtiles` wrote to OUT/, and a
//! page that shows it (viewer/index.html: three.js and 3DTilesRendererJS,
//! installed by viewer/install.sh), over HTTP on 127.0.0.1 only.
//!
//! Routes: `/` is the page, `/tiles/...` the tileset's files, `/vendor/...`
//! the page's JavaScript packages. Only plain relative paths are served:
//! a segment that is empty, starts with a dot or holds anything but
//! letters, digits, `-`, `_` and `.` is not found, so no request leaves the
//! two folders.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use tiny_http::{Header, Response, Server};

/// The page, built into the binary.
const PAGE: &str = include_str!("../../../viewer/index.html");

/// Where viewer/install.sh puts the page's packages in a checkout.
const VENDOR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../viewer/node_modules");

/// Threads answering requests (a tileset is many small files).
const WORKERS: usize = 4;

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
    let server = Server::http(("127.0.0.1", port)).map_err(|e| anyhow::anyhow!("127.0.0.1:{port}: {e}"))?;
    let port = server.server_addr().to_ip().map_or(port, |a| a.port());
    // A script waiting for the server reads this line.
    println!("serving {} at http://127.0.0.1:{port}/", tiles.display());
    std::io::stdout().flush().context("stdout")?;
    std::thread::scope(|s| {
        for _ in 0..WORKERS {
            s.spawn(|| {
                for request in server.incoming_requests() {
                    let response = answer(request.url(), tiles, &vendor);
                    // A client that went away is no error of the server's.
                    let _ = request.respond(response);
                }
            });
        }
    });
    Ok(())
}

/// The response to a GET of `url`.
fn answer(url: &str, tiles: &Path, vendor: &Path) -> Response<std::io::Cursor<Vec<u8>>> {
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
        Some((bytes, kind)) => Response::from_data(bytes).with_header(header("Content-Type", kind)),
        None => Response::from_data(b"not found".to_vec()).with_status_code(404),
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

fn header(name: &str, value: &str) -> Header {
    Header::from_bytes(name.as_bytes(), value.as_bytes()).expect("ASCII header")
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
        assert_eq!(answer("/", root, root).status_code().0, 200);
        assert_eq!(answer("/?error=4", root, root).status_code().0, 200);
        assert_eq!(answer("/tiles/Cargo.toml", root, root).status_code().0, 200);
        assert_eq!(answer("/tiles/../Cargo.toml", root, root).status_code().0, 404);
        assert_eq!(answer("/elsewhere", root, root).status_code().0, 404);
    }
}
