//! `treemanip-server --health-check`: the container's health check without
//! curl in the image. One `GET /healthz` over loopback to the port the
//! server listens on; healthy means a `200` status line within the timeout.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::Duration;

/// Where to reach a server bound to `bind`: an unspecified address
/// (`0.0.0.0`, `::`) is reached on loopback.
pub fn loopback_for(bind: SocketAddr) -> SocketAddr {
    let mut addr = bind;
    if addr.ip().is_unspecified() {
        addr.set_ip(match addr {
            SocketAddr::V4(_) => std::net::Ipv4Addr::LOCALHOST.into(),
            SocketAddr::V6(_) => std::net::Ipv6Addr::LOCALHOST.into(),
        });
    }
    addr
}

/// `Ok` when `GET /healthz` on `addr` answers 200 within `timeout`.
pub fn check(addr: SocketAddr, timeout: Duration) -> Result<(), String> {
    let mut stream = TcpStream::connect_timeout(&addr, timeout)
        .map_err(|e| format!("cannot connect to {addr}: {e}"))?;
    stream
        .set_read_timeout(Some(timeout))
        .and_then(|_| stream.set_write_timeout(Some(timeout)))
        .map_err(|e| e.to_string())?;
    // One write: `write!` on the bare stream sends each formatted piece
    // apart, and a server that answers and closes after the first piece
    // (the request line is enough to route it) breaks the pipe under the
    // rest.
    let request = format!("GET /healthz HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n");
    stream
        .write_all(request.as_bytes())
        .map_err(|e| format!("cannot send to {addr}: {e}"))?;
    let mut head = [0u8; 64];
    let mut got = 0;
    while got < 12 {
        match stream.read(&mut head[got..]) {
            Ok(0) => break,
            Ok(k) => got += k,
            Err(e) => return Err(format!("no answer from {addr}: {e}")),
        }
    }
    let line = String::from_utf8_lossy(&head[..got]);
    match line.split_whitespace().nth(1) {
        Some("200") => Ok(()),
        Some(status) => Err(format!("{addr}/healthz answered {status}")),
        None => Err(format!("{addr}/healthz: not an HTTP answer")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::TcpListener;

    #[test]
    fn unspecified_binds_are_probed_on_loopback() {
        let a = loopback_for("0.0.0.0:8080".parse().unwrap());
        assert_eq!(a, "127.0.0.1:8080".parse().unwrap());
        let b = loopback_for("10.1.2.3:9".parse().unwrap());
        assert_eq!(b, "10.1.2.3:9".parse().unwrap());
    }

    #[test]
    fn healthy_only_on_a_200() {
        for (answer, healthy) in [
            ("HTTP/1.1 200 OK\r\ncontent-length: 0\r\n\r\n", true),
            ("HTTP/1.1 503 Service Unavailable\r\n\r\n", false),
            ("garbage", false),
        ] {
            let listener = TcpListener::bind("127.0.0.1:0").unwrap();
            let addr = listener.local_addr().unwrap();
            // Only the probe's own request is answered: another test that
            // connects to a port it saw closed may reach this listener
            // when the port number is reused, and must not take its answer.
            let server = std::thread::spawn(move || {
                loop {
                    let (mut s, _) = listener.accept().unwrap();
                    s.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
                    let mut buf = [0u8; 256];
                    let n = s.read(&mut buf).unwrap_or(0);
                    if buf[..n].starts_with(b"GET /healthz") {
                        s.write_all(answer.as_bytes()).unwrap();
                        break;
                    }
                }
            });
            let result = check(addr, Duration::from_secs(2));
            assert_eq!(result.is_ok(), healthy, "{answer}: {result:?}");
            server.join().unwrap();
        }
        // Nothing listening: unhealthy, with the reason.
        let closed = TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap();
        assert!(
            check(closed, Duration::from_millis(500))
                .unwrap_err()
                .contains("connect")
        );
    }
}
