//! Claims: `mktree serve` answers the page, the tileset's files and the
//! page's packages on 127.0.0.1 and nothing outside its two folders, and
//! refuses a folder without a tileset in one line; `mktree bench-view`
//! keeps every frame's error within τ and every budgeted frame within its
//! reads, and writes its JSON, chart (the PNG with its title and axis labels
//! drawn) and frame strip.

mod common;

use std::io::{Read, Write};
use std::net::TcpStream;

use common::{mktree, serve, tanker1_in};

/// The status code and body of `GET path` from the server at `port`.
fn get(port: u16, path: &str) -> (u16, Vec<u8>) {
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    // HTTP/1.0: the body comes whole, not chunked.
    write!(s, "GET {path} HTTP/1.0\r\n\r\n").unwrap();
    let mut response = Vec::new();
    s.read_to_end(&mut response).unwrap();
    let head_end = response.windows(4).position(|w| w == b"\r\n\r\n").expect("a response head");
    let status = String::from_utf8_lossy(&response[9..12]).parse().unwrap();
    (status, response[head_end + 4..].to_vec())
}

#[test]
fn serve_answers_the_page_the_tiles_and_the_packages_and_nothing_else() {
    let dir = tempfile::tempdir().unwrap();
    let (_, mkt) = tanker1_in(dir.path());
    let tiles = dir.path().join("tiles");
    let out = mktree().arg("export-3dtiles").arg(&mkt).arg(&tiles).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // Stand-ins for the npm packages viewer/install.sh installs.
    let vendor = dir.path().join("vendor");
    std::fs::create_dir_all(vendor.join("three/build")).unwrap();
    std::fs::create_dir_all(vendor.join("3d-tiles-renderer/build")).unwrap();
    std::fs::write(vendor.join("three/build/three.module.js"), "export const REVISION = '0';").unwrap();
    std::fs::write(dir.path().join("secret.txt"), "not served").unwrap();

    let (server, port) = serve(dir.path());

    let (status, page) = get(port, "/");
    assert_eq!(status, 200);
    assert!(String::from_utf8_lossy(&page).contains("TilesRenderer"), "the page loads the tiles renderer");
    let (status, tileset) = get(port, "/tiles/tileset.json");
    assert_eq!(status, 200);
    assert_eq!(tileset, std::fs::read(tiles.join("tileset.json")).unwrap());
    let (status, js) = get(port, "/vendor/three/build/three.module.js");
    assert_eq!((status, js.as_slice()), (200, b"export const REVISION = '0';".as_slice()));
    for outside in [
        "/tiles/../secret.txt",
        "/tiles/%2e%2e/secret.txt",
        "/vendor/../secret.txt",
        "/secret.txt",
        "/tiles/",
    ] {
        assert_eq!(get(port, outside).0, 404, "{outside}");
    }
    drop(server);

    // A folder with no tileset is refused in one line.
    let out = mktree().arg("serve").arg(dir.path()).args(["--port", "0"]).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(stderr.contains("tileset.json"), "{stderr}");
}

#[test]
fn bench_view_keeps_errors_within_tau_and_reads_within_budgets() {
    let dir = tempfile::tempdir().unwrap();
    let (_, mkt) = tanker1_in(dir.path());
    let out_dir = dir.path().join("bench");
    let out = mktree()
        .arg("bench-view")
        .arg(&mkt)
        .args([
            "--steps",
            "4",
            "--taus",
            "0,8,64",
            "--budgets",
            "3,10",
            "--height-px",
            "120",
            "--cache-blocks",
            "8",
        ])
        .arg("--out")
        .arg(&out_dir)
        .arg("--json")
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let bench = &v[0]["bench"];
    assert_eq!(bench["frames"], 4);
    assert!(bench["exact_frustum_reads"].as_f64().unwrap() > 0.0);
    let taus = bench["taus"].as_array().unwrap();
    assert_eq!(taus.len(), 3);
    for row in taus {
        let tau = row["tau_px"].as_f64().unwrap();
        assert!(row["max_error_px"].as_f64().unwrap() <= tau + 1e-9, "{row}");
    }
    assert_eq!(taus[0]["max_error_px"], 0.0, "tau 0 draws every visible object exact");
    assert!(taus[0]["triangles"].as_f64().unwrap() > 0.0);
    for row in bench["budgets"].as_array().unwrap() {
        assert!(row["reads"].as_f64().unwrap() <= row["budget"].as_f64().unwrap(), "{row}");
    }
    for file in ["bench-view.json", "bench-view.svg", "bench-view.png", "frames-t1.png"] {
        assert!(std::fs::metadata(out_dir.join(file)).unwrap().len() > 0, "{file}");
    }
    common::assert_chart_has_text(&out_dir.join("bench-view.png"));
    let out = mktree().arg("bench-view").arg(&mkt).arg("--taus=-1").output().unwrap();
    assert_eq!(out.status.code(), Some(1), "a negative tau is refused");
}
