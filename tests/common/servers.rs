//! Real servers on 127.0.0.1 for the object-store tests: nginx (Debian's
//! package) for plain HTTP ranges and moto's S3 server (PyPI `moto[server]`)
//! for the S3 protocol. `.ci/install-servers.sh` installs both. A server
//! that is not installed skips its test with a note, unless
//! `MKTREE_REMOTE_TESTS=required` (set by `.ci/run`) makes that a failure.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A server process, killed when dropped.
pub struct Server {
    child: Child,
    /// The port it listens on, on 127.0.0.1.
    pub port: u16,
    /// Its working folder (nginx: `www/` is served, `access.log` is its log).
    pub dir: tempfile::TempDir,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Server {
    /// The requests the server logged (nginx's access log), one per line.
    pub fn logged_requests(&self) -> Vec<String> {
        std::fs::read_to_string(self.dir.path().join("access.log"))
            .unwrap_or_default()
            .lines()
            .map(str::to_string)
            .collect()
    }

    /// The logged requests once there are at least `n` (nginx logs a
    /// request after its answer is sent, so a client can be ahead of the
    /// log), or after 5 s, whatever they are then.
    pub fn logged_requests_once(&self, n: usize) -> Vec<String> {
        let until = Instant::now() + Duration::from_secs(5);
        loop {
            let lines = self.logged_requests();
            if lines.len() >= n || Instant::now() > until {
                return lines;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }
}

/// `None` (and a note) when the program is missing and the tests are not
/// required; a panic when they are.
fn missing(what: &str) -> Option<Server> {
    if std::env::var("MKTREE_REMOTE_TESTS").is_ok_and(|v| v == "required") {
        panic!("{what} is not installed (bash .ci/install-servers.sh installs it)");
    }
    eprintln!("skipped: {what} is not installed (bash .ci/install-servers.sh installs it)");
    None
}

/// A port free on 127.0.0.1 and not given to another server of this
/// process (tests run in parallel, and the system may offer one port twice
/// once it is closed again).
fn free_port() -> u16 {
    static GIVEN: std::sync::Mutex<Vec<u16>> = std::sync::Mutex::new(Vec::new());
    let mut given = GIVEN.lock().unwrap_or_else(|p| p.into_inner());
    loop {
        let port = TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .expect("a free port on 127.0.0.1")
            .port();
        if !given.contains(&port) {
            given.push(port);
            return port;
        }
    }
}

fn wait_until_listening(port: u16, child: &mut Child, what: &str) {
    let start = Instant::now();
    // A connect to a port nobody listens on can meet itself (the system
    // may pick that port as the connection's own): that is not the server.
    let listening = || {
        TcpStream::connect(("127.0.0.1", port))
            .is_ok_and(|s| s.local_addr().ok().zip(s.peer_addr().ok()).is_some_and(|(a, b)| a != b))
    };
    while !listening() {
        if let Ok(Some(status)) = child.try_wait() {
            panic!("{what} exited before it listened: {status}");
        }
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "{what} did not listen on port {port} within 30 s"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    // Another program on the port would have answered the connect: ours
    // must still be running.
    std::thread::sleep(Duration::from_millis(100));
    if let Ok(Some(status)) = child.try_wait() {
        panic!("{what} exited after port {port} answered (another program holds it): {status}");
    }
}

fn find_program(env: &str, names: &[&str]) -> Option<PathBuf> {
    if let Ok(p) = std::env::var(env) {
        return Some(PathBuf::from(p));
    }
    let path = std::env::var_os("PATH")?;
    let dirs: Vec<PathBuf> =
        std::env::split_paths(&path).chain(["/usr/sbin".into(), "/sbin".into()]).collect();
    names.iter().flat_map(|n| dirs.iter().map(move |d| d.join(n))).find(|p| p.is_file())
}

/// nginx serving a fresh `www/` folder on 127.0.0.1, logging each request.
pub fn nginx() -> Option<Server> {
    let Some(program) = find_program("MKTREE_NGINX", &["nginx"]) else { return missing("nginx") };
    let dir = tempfile::tempdir().expect("a temporary folder");
    let d = dir.path().display();
    std::fs::create_dir(dir.path().join("www")).expect("www folder");
    let port = free_port();
    let conf = format!(
        "daemon off;\nmaster_process off;\nworker_processes 1;\npid {d}/nginx.pid;\nerror_log {d}/error.log;\n\
         events {{ worker_connections 64; }}\n\
         http {{\n  access_log {d}/access.log;\n  client_body_temp_path {d}/body;\n  proxy_temp_path {d}/proxy;\n  \
         fastcgi_temp_path {d}/fastcgi;\n  uwsgi_temp_path {d}/uwsgi;\n  scgi_temp_path {d}/scgi;\n  \
         server {{ listen 127.0.0.1:{port}; root {d}/www; }}\n}}\n"
    );
    std::fs::write(dir.path().join("nginx.conf"), conf).expect("nginx.conf");
    let mut child = Command::new(program)
        .arg("-p")
        .arg(dir.path())
        .arg("-c")
        .arg(dir.path().join("nginx.conf"))
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("nginx starts");
    wait_until_listening(port, &mut child, "nginx");
    Some(Server { child, port, dir })
}

/// moto's S3 server on 127.0.0.1 (anything signed is accepted).
pub fn moto() -> Option<Server> {
    let Some(program) = find_program("MKTREE_MOTO_SERVER", &["moto_server"]) else {
        return missing("moto_server (pip install 'moto[server]')");
    };
    let dir = tempfile::tempdir().expect("a temporary folder");
    let port = free_port();
    let mut child = Command::new(program)
        .args(["-H", "127.0.0.1", "-p", &port.to_string()])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("moto_server starts");
    wait_until_listening(port, &mut child, "moto_server");
    Some(Server { child, port, dir })
}

/// A connection to 127.0.0.1:`port`, tried again for up to 5 s while it is
/// refused: once (of many CI runs) a moto server that had answered the
/// start-up check refused the test's first request a second later.
fn connect(port: u16) -> TcpStream {
    let start = Instant::now();
    loop {
        match TcpStream::connect(("127.0.0.1", port)) {
            Ok(s) => return s,
            Err(e)
                if e.kind() == std::io::ErrorKind::ConnectionRefused
                    && start.elapsed() < Duration::from_secs(5) =>
            {
                std::thread::sleep(Duration::from_millis(100));
            }
            Err(e) => panic!("connect to 127.0.0.1:{port}: {e}"),
        }
    }
}

/// One HTTP/1.1 request to 127.0.0.1:`port`; the status code.
pub fn http(port: u16, method: &str, path: &str, body: &[u8]) -> u16 {
    let mut s = connect(port);
    let head = format!(
        "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        body.len()
    );
    s.write_all(head.as_bytes()).and_then(|_| s.write_all(body)).expect("send");
    let mut answer = Vec::new();
    s.read_to_end(&mut answer).expect("answer");
    let text = String::from_utf8_lossy(&answer);
    text.split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or_else(|| panic!("no status in {text:?}"))
}

/// The S3 settings that reach moto on `port`.
pub fn s3_options(port: u16) -> Vec<(String, String)> {
    [
        ("aws_endpoint", format!("http://127.0.0.1:{port}")),
        ("aws_allow_http", "true".into()),
        ("aws_access_key_id", "test".into()),
        ("aws_secret_access_key", "test".into()),
        ("aws_region", "us-east-1".into()),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect()
}

/// Puts `bytes` as `key` in `bucket` of the S3 server on `port`, signed
/// (moto refuses unsigned requests to an object that exists).
pub fn s3_put(port: u16, bucket: &str, key: &str, bytes: &[u8]) {
    use object_store::ObjectStore;
    let mut builder = object_store::aws::AmazonS3Builder::new().with_bucket_name(bucket);
    for (k, v) in s3_options(port) {
        builder = builder.with_config(k.parse().expect("an S3 setting"), v);
    }
    let store = builder.build().expect("an S3 client");
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().expect("a runtime");
    rt.block_on(store.put(&key.into(), bytes.to_vec().into())).expect("put");
}

/// Writes `bytes` as `path`, replacing it in one rename (as a deploy would).
pub fn replace_file(path: &Path, bytes: &[u8]) {
    let tmp = path.with_extension("part");
    std::fs::write(&tmp, bytes).expect("write");
    std::fs::rename(&tmp, path).expect("rename");
}

/// What [`faulty`] does once it has answered `after` requests well.
#[derive(Debug, Clone, Copy)]
pub enum Fault {
    /// Answers 503 to every request.
    ServerError,
    /// Announces the whole range, sends half of it and closes.
    Truncate,
    /// Sends the range with one byte changed.
    Flip,
}

/// A server on 127.0.0.1 that serves `file` (any path) by HTTP range
/// requests, with a fixed ETag, and after `after` good answers fails as
/// `fault` says: a fault injector for the object-store reader, beside the
/// real servers above. Its thread ends with the process.
pub fn faulty(file: Vec<u8>, after: usize, fault: Fault) -> u16 {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let port = listener.local_addr().expect("address").port();
    std::thread::spawn(move || {
        for (n, stream) in listener.incoming().enumerate() {
            let Ok(mut s) = stream else { continue };
            let Some(range) = read_range(&mut s, file.len()) else { continue };
            let mut body = file[range.clone()].to_vec();
            let head = |status: &str, len: usize| {
                format!(
                    "HTTP/1.1 {status}\r\nContent-Length: {len}\r\nContent-Range: bytes {}-{}/{}\r\n\
                     ETag: \"fixed\"\r\nAccept-Ranges: bytes\r\nConnection: close\r\n\r\n",
                    range.start,
                    range.end - 1,
                    file.len()
                )
            };
            let _ = match (n >= after).then_some(fault) {
                None => s
                    .write_all(head("206 Partial Content", body.len()).as_bytes())
                    .and_then(|_| s.write_all(&body)),
                Some(Fault::ServerError) => s.write_all(
                    b"HTTP/1.1 503 Service Unavailable\r\nContent-Length: 0\r\nConnection: close\r\n\r\n",
                ),
                Some(Fault::Truncate) => s
                    .write_all(head("206 Partial Content", body.len()).as_bytes())
                    .and_then(|_| s.write_all(&body[..body.len() / 2])),
                Some(Fault::Flip) => {
                    let mid = body.len() / 2;
                    body[mid] ^= 0x5a;
                    s.write_all(head("206 Partial Content", body.len()).as_bytes())
                        .and_then(|_| s.write_all(&body))
                }
            };
        }
    });
    port
}

/// The byte range a request asks for (`Range: bytes=a-b`, clipped to the
/// file), after reading its head.
fn read_range(s: &mut TcpStream, len: usize) -> Option<std::ops::Range<usize>> {
    let mut head = Vec::new();
    let mut byte = [0u8; 1];
    while !head.ends_with(b"\r\n\r\n") {
        if s.read(&mut byte).ok()? == 0 {
            return None;
        }
        head.push(byte[0]);
    }
    let text = String::from_utf8_lossy(&head).to_ascii_lowercase();
    let spec = text.lines().find_map(|l| l.strip_prefix("range: bytes="))?;
    let (a, b) = spec.trim().split_once('-')?;
    let start: usize = a.parse().ok()?;
    let end = b.parse::<usize>().map_or(len, |b| (b + 1).min(len));
    (start < end).then_some(start..end)
}
