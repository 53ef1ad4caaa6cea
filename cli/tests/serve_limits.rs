//! Claims (issue 39): `mktree serve` streams a file of several GiB with its
//! peak resident memory under its stated bound (96 MiB), also while other
//! clients stall mid-download and hundreds sit silent, and keeps
//! answering; it answers a range request with 206 and exactly the bytes
//! asked for; and it refuses a symbolic link that leaves the tiles folder
//! (one to /etc/passwd) while serving one that stays inside; clients that
//! leave mid-download do not end it.

mod common;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::time::Duration;

use common::serve;

/// The bound `serve` states (cli/src/cmd/serve.rs, `MEMORY_BOUND`).
const MEMORY_BOUND: u64 = 96 << 20;

/// Sends `GET path` with `extra` header lines; returns the stream and the
/// response head, the body left unread.
fn request(port: u16, path: &str, extra: &str) -> (BufReader<TcpStream>, String) {
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    write!(s, "GET {path} HTTP/1.1\r\nHost: test\r\nConnection: close\r\n{extra}\r\n").unwrap();
    let mut r = BufReader::new(s);
    let mut head = String::new();
    loop {
        let mut line = String::new();
        assert!(r.read_line(&mut line).unwrap() > 0, "the server closed before the head ended: {head}");
        if line == "\r\n" {
            return (r, head);
        }
        head.push_str(&line);
    }
}

fn status(head: &str) -> u16 {
    head[9..12].parse().unwrap()
}

fn header<'h>(head: &'h str, name: &str) -> Option<&'h str> {
    head.lines().find_map(|l| {
        let (n, v) = l.split_once(':')?;
        n.eq_ignore_ascii_case(name).then(|| v.trim())
    })
}

fn get(port: u16, path: &str, extra: &str) -> (u16, String, Vec<u8>) {
    let (mut r, head) = request(port, path, extra);
    let mut body = Vec::new();
    r.read_to_end(&mut body).unwrap();
    (status(&head), head, body)
}

/// A kernel figure of `pid`'s, in bytes (`VmHWM`: peak resident memory).
fn status_bytes(pid: u32, field: &str) -> u64 {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    let line = s.lines().find_map(|l| l.strip_prefix(field)).unwrap();
    line.trim().strip_suffix("kB").unwrap().trim().parse::<u64>().unwrap() * 1024
}

fn tiles_with_a_big_file(dir: &Path, big: u64) {
    let tiles = dir.join("tiles");
    std::fs::create_dir_all(&tiles).unwrap();
    std::fs::write(tiles.join("tileset.json"), r#"{"asset":{"version":"1.1"}}"#).unwrap();
    // Sparse: no disk space, and reading it costs no disk time.
    std::fs::File::create(tiles.join("big.glb")).unwrap().set_len(big).unwrap();
    std::fs::write(tiles.join("digits.bin"), (0..=255u8).cycle().take(100_000).collect::<Vec<u8>>()).unwrap();
}

#[cfg(target_os = "linux")]
#[test]
fn serve_streams_a_3_gib_file_within_its_memory_bound_beside_stalled_and_silent_clients() {
    let dir = tempfile::tempdir().unwrap();
    let big = 3u64 << 30;
    tiles_with_a_big_file(dir.path(), big);
    let (mut server, port) = serve(dir.path());
    let pid = server.0.id();

    // Silent clients: connected, never a byte sent.
    let silent: Vec<TcpStream> = (0..250).map(|_| TcpStream::connect(("127.0.0.1", port)).unwrap()).collect();
    // Stalled clients: the download started, then nothing read.
    let stalled: Vec<_> = (0..3)
        .map(|_| {
            let (mut r, head) = request(port, "/tiles/big.glb", "");
            assert_eq!(status(&head), 200, "{head}");
            let mut first = vec![0u8; 1 << 20];
            r.read_exact(&mut first).unwrap();
            r
        })
        .collect();

    // One client reads the whole file.
    let (mut r, head) = request(port, "/tiles/big.glb", "");
    assert_eq!(status(&head), 200, "{head}");
    assert_eq!(header(&head, "content-length"), Some(big.to_string().as_str()));
    assert_eq!(header(&head, "content-type"), Some("model/gltf-binary"));
    let mut buf = vec![0u8; 1 << 20];
    let mut got = 0u64;
    loop {
        let n = r.read(&mut buf).unwrap();
        if n == 0 {
            break;
        }
        assert!(buf[..n].iter().all(|&b| b == 0), "a sparse file reads as zeros");
        got += n as u64;
    }
    assert_eq!(got, big);

    // Still answering, with every other client still connected.
    let (code, _, body) = get(port, "/tiles/tileset.json", "");
    assert_eq!((code, body.as_slice()), (200, br#"{"asset":{"version":"1.1"}}"#.as_slice()));
    let peak = status_bytes(pid, "VmHWM:");
    println!("serve's peak resident memory: {:.1} MiB after {} MiB sent", peak as f64 / 1048576.0, big >> 20);
    assert!(peak < MEMORY_BOUND, "peak {peak} bytes, over the stated bound {MEMORY_BOUND}");

    // Clients that leave mid-download (unread bytes: the kernel resets the
    // connection) cost the server nothing: it lived on SIGPIPE's default
    // action once, and died here.
    drop((silent, stalled));
    let leaving: Vec<_> = (0..8)
        .map(|_| {
            std::thread::spawn(move || {
                let (mut r, _) = request(port, "/tiles/big.glb", "");
                let mut buf = vec![0u8; 1 << 20];
                for _ in 0..64 {
                    r.read_exact(&mut buf).unwrap();
                }
            })
        })
        .collect();
    for t in leaving {
        t.join().unwrap();
    }
    std::thread::sleep(Duration::from_millis(500));
    let (code, _, _) = get(port, "/tiles/big.glb", "Range: bytes=0-9\r\n");
    assert_eq!(code, 206);
    assert!(server.0.try_wait().unwrap().is_none(), "the server ended when clients left");
}

#[test]
fn serve_answers_a_range_request_with_206_and_the_bytes_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    tiles_with_a_big_file(dir.path(), 3 << 30);
    let (_server, port) = serve(dir.path());
    let digits: Vec<u8> = (0..=255u8).cycle().take(100_000).collect();

    let (code, head, body) = get(port, "/tiles/digits.bin", "Range: bytes=1000-1099\r\n");
    assert_eq!(code, 206, "{head}");
    assert_eq!(header(&head, "content-range"), Some("bytes 1000-1099/100000"));
    assert_eq!(body, &digits[1000..1100]);

    let (code, _, body) = get(port, "/tiles/digits.bin", "Range: bytes=-10\r\n");
    assert_eq!((code, body.as_slice()), (206, &digits[99_990..]));

    // The end of the 3 GiB file, without sending the rest.
    let end = (3u64 << 30) - 1;
    let (code, head, body) = get(port, "/tiles/big.glb", &format!("Range: bytes={}-\r\n", end - 99));
    assert_eq!(code, 206, "{head}");
    assert_eq!(body, vec![0u8; 100]);

    let (code, _, _) = get(port, "/tiles/digits.bin", "Range: bytes=200000-\r\n");
    assert_eq!(code, 416, "a range past the end is not satisfiable");
}

#[cfg(unix)]
#[test]
fn serve_refuses_a_link_that_leaves_the_tiles_folder() {
    let dir = tempfile::tempdir().unwrap();
    tiles_with_a_big_file(dir.path(), 1);
    let tiles = dir.path().join("tiles");
    std::os::unix::fs::symlink("/etc/passwd", tiles.join("passwd.json")).unwrap();
    std::os::unix::fs::symlink("/etc", tiles.join("etc")).unwrap();
    std::fs::write(dir.path().join("secret.txt"), "not served").unwrap();
    std::os::unix::fs::symlink(dir.path().join("secret.txt"), tiles.join("secret.txt")).unwrap();
    std::os::unix::fs::symlink(tiles.join("tileset.json"), tiles.join("alias.json")).unwrap();
    let (_server, port) = serve(dir.path());

    for outside in ["/tiles/passwd.json", "/tiles/etc/passwd", "/tiles/secret.txt"] {
        let (code, _, body) = get(port, outside, "");
        assert_eq!(code, 404, "{outside}: {}", String::from_utf8_lossy(&body));
    }
    let (code, _, body) = get(port, "/tiles/alias.json", "");
    assert_eq!((code, body.as_slice()), (200, br#"{"asset":{"version":"1.1"}}"#.as_slice()), "a link inside");
}
