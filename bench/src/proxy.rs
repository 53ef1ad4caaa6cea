//! A TCP proxy on 127.0.0.1 that adds a round-trip delay between a client
//! and one server, for `mktree bench-remote`: every chunk read from one
//! side is written to the other half a round trip after it arrived, in the
//! order it arrived.
//!
//! So a request and its answer cost one added round trip, as on a real
//! network, and chunks sent back to back (requests pipelined on one
//! connection, the pieces of a long answer) are not serialized: each waits
//! from its own arrival, not from the previous chunk's delivery. What it
//! does not add: the TCP handshake is with the proxy, which connects to
//! the server at once, so opening a connection costs no added round trip
//! (a real network charges one, TLS one or two more). A client's first
//! requests on new connections are therefore optimistic.
//!
//! Plain threads, no runtime: per connection one reader and one writer for
//! each direction, joined by a channel of (due time, chunk).

use std::collections::HashMap;
use std::io::{self, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Bytes read from a socket at a time: one chunk.
const CHUNK: usize = 64 * 1024;

/// How long the proxy waits for the server to accept a connection.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(10);

/// A running proxy: connections to [`LatencyProxy::addr`] are forwarded to
/// the server, each chunk delayed by half the round trip each way. Dropping
/// it stops accepting and closes every connection it forwards.
pub struct LatencyProxy {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    live: Live,
    accept: Option<JoinHandle<()>>,
}

/// Both sockets of every open connection, by number, so that dropping the
/// proxy can close them and end their threads.
type Live = Arc<Mutex<HashMap<u64, [TcpStream; 2]>>>;

impl LatencyProxy {
    /// Listens on a free port of 127.0.0.1 and forwards each connection to
    /// `upstream`, adding `round_trip` to every request and answer.
    pub fn start(upstream: SocketAddr, round_trip: Duration) -> io::Result<LatencyProxy> {
        let listener = TcpListener::bind(("127.0.0.1", 0))?;
        let addr = listener.local_addr()?;
        let stop = Arc::new(AtomicBool::new(false));
        let live: Live = Arc::default();
        let accept = {
            let (stop, live) = (stop.clone(), live.clone());
            std::thread::Builder::new()
                .name("latency-proxy".into())
                .spawn(move || accept_loop(&listener, upstream, round_trip / 2, &stop, &live))?
        };
        Ok(LatencyProxy { addr, stop, live, accept: Some(accept) })
    }

    /// The address clients connect to.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }
}

impl Drop for LatencyProxy {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        // The accept loop blocks in accept: a connection wakes it to see the flag.
        let _ = TcpStream::connect_timeout(&self.addr, Duration::from_secs(1));
        if let Some(accept) = self.accept.take() {
            let _ = accept.join();
        }
        // Closing both sockets ends the readers; the writers end with them.
        for sockets in lock(&self.live).values() {
            for s in sockets {
                let _ = s.shutdown(Shutdown::Both);
            }
        }
    }
}

fn lock(live: &Live) -> std::sync::MutexGuard<'_, HashMap<u64, [TcpStream; 2]>> {
    // A panic while holding the lock leaves whole entries behind.
    live.lock().unwrap_or_else(|p| p.into_inner())
}

fn accept_loop(listener: &TcpListener, upstream: SocketAddr, half: Duration, stop: &AtomicBool, live: &Live) {
    let next = AtomicU64::new(0);
    for client in listener.incoming() {
        if stop.load(Ordering::SeqCst) {
            return;
        }
        // A connection that fails here is dropped: the client sees it
        // closed, as it would a server that went away.
        let Ok(client) = client else { continue };
        let Ok(server) = TcpStream::connect_timeout(&upstream, CONNECT_TIMEOUT) else { continue };
        let id = next.fetch_add(1, Ordering::Relaxed);
        if forward(id, client, server, half, live).is_err() {
            lock(live).remove(&id);
        }
    }
}

/// Starts the four threads of one connection.
fn forward(id: u64, client: TcpStream, server: TcpStream, half: Duration, live: &Live) -> io::Result<()> {
    // Nagle's algorithm would hold small chunks back and add delays of its own.
    client.set_nodelay(true)?;
    server.set_nodelay(true)?;
    lock(live).insert(id, [client.try_clone()?, server.try_clone()?]);
    // The second direction to finish removes the connection's entry.
    let done = Arc::new(AtomicBool::new(false));
    for (from, to) in [(client.try_clone()?, server.try_clone()?), (server, client)] {
        let (done, live) = (done.clone(), live.clone());
        let finish = move || {
            if done.swap(true, Ordering::SeqCst) {
                lock(&live).remove(&id);
            }
        };
        pump(from, to, half, finish)?;
    }
    Ok(())
}

/// One direction: a reader stamps each chunk with its due time, a writer
/// sends it then. At the end of the input the output's write half is shut
/// down, half a round trip later too, so the peer sees the end in order.
fn pump(
    mut from: TcpStream,
    mut to: TcpStream,
    half: Duration,
    finish: impl FnOnce() + Send + 'static,
) -> io::Result<()> {
    let (tx, rx) = mpsc::channel::<(Instant, Option<Vec<u8>>)>();
    let wake = from.try_clone()?;
    std::thread::Builder::new().name("latency-proxy-read".into()).spawn(move || {
        let mut buf = vec![0u8; CHUNK];
        loop {
            let chunk = match from.read(&mut buf) {
                Ok(0) | Err(_) => None,
                Ok(n) => buf.get(..n).map(<[u8]>::to_vec),
            };
            let end = chunk.is_none();
            // The writer is gone when its side failed: nothing more to send.
            if tx.send((Instant::now() + half, chunk)).is_err() || end {
                return;
            }
        }
    })?;
    std::thread::Builder::new().name("latency-proxy-write".into()).spawn(move || {
        for (due, chunk) in rx {
            std::thread::sleep(due.saturating_duration_since(Instant::now()));
            match chunk {
                Some(bytes) if to.write_all(&bytes).is_ok() => {}
                Some(_) => {
                    // The receiving side is gone: stop reading the sending side.
                    let _ = wake.shutdown(Shutdown::Both);
                    break;
                }
                None => {
                    let _ = to.shutdown(Shutdown::Write);
                    break;
                }
            }
        }
        finish();
    })?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A server on 127.0.0.1 that echoes every connection's bytes back.
    fn echo_server() -> SocketAddr {
        let listener = TcpListener::bind(("127.0.0.1", 0)).unwrap();
        let addr = listener.local_addr().unwrap();
        std::thread::spawn(move || {
            for s in listener.incoming() {
                let Ok(mut s) = s else { return };
                std::thread::spawn(move || {
                    let mut back = s.try_clone().unwrap();
                    let _ = io::copy(&mut s, &mut back);
                });
            }
        });
        addr
    }

    #[test]
    fn a_request_and_its_answer_cost_one_round_trip_and_keep_their_order() {
        let round_trip = Duration::from_millis(100);
        let proxy = LatencyProxy::start(echo_server(), round_trip).unwrap();
        let mut s = TcpStream::connect(proxy.addr()).unwrap();
        s.set_nodelay(true).unwrap();
        let started = Instant::now();
        s.write_all(b"ping").unwrap();
        let mut got = [0u8; 4];
        s.read_exact(&mut got).unwrap();
        assert_eq!(&got, b"ping");
        assert!(started.elapsed() >= round_trip, "{:?}", started.elapsed());

        // Five chunks sent 10 ms apart come back whole and in order, about
        // one round trip after the last: delayed together, not one after
        // another (five round trips). The bound is loose: machines are noisy.
        let started = Instant::now();
        for i in 0..5u8 {
            s.write_all(&[b'a' + i; 3]).unwrap();
            std::thread::sleep(Duration::from_millis(10));
        }
        let mut got = [0u8; 15];
        s.read_exact(&mut got).unwrap();
        assert_eq!(&got, b"aaabbbcccdddeee");
        let took = started.elapsed();
        assert!(took >= round_trip + Duration::from_millis(40), "{took:?}");
        assert!(took < round_trip * 4, "pipelined chunks were serialized: {took:?}");
    }

    #[test]
    fn dropping_the_proxy_closes_its_connections() {
        let proxy = LatencyProxy::start(echo_server(), Duration::ZERO).unwrap();
        let mut s = TcpStream::connect(proxy.addr()).unwrap();
        s.write_all(b"x").unwrap();
        let mut got = [0u8; 1];
        s.read_exact(&mut got).unwrap();
        drop(proxy);
        s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        // The end of the stream, or a reset: not a hang (a timeout).
        match s.read(&mut got) {
            Ok(n) => assert_eq!(n, 0),
            Err(e) => {
                assert!(!matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut), "{e}")
            }
        }
    }
}
