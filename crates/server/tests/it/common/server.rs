//! A `treemanip-server` process on a free loopback port, spoken to over
//! real HTTP/1.1 with ureq (a maintained client). The trainer's tests and
//! the benches include this file too (`#[path]`), so there is one way to
//! start and talk to a server.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use serde_json::Value;

/// The `treemanip-server` binary of this build profile: cargo's own path
/// for the server crate's tests; beside the `treemanip` binary for the
/// trainer's tests (cargo gives that package no `CARGO_BIN_EXE_` for
/// another package's binary: the README's test command, `--workspace`,
/// builds it first). A bench needs `cargo build --release --bin
/// treemanip-server` first.
pub fn server_exe() -> std::path::PathBuf {
    let exe = match (
        option_env!("CARGO_BIN_EXE_treemanip-server"),
        option_env!("CARGO_BIN_EXE_treemanip"),
    ) {
        (Some(server), _) => std::path::PathBuf::from(server),
        (None, Some(cli)) => std::path::Path::new(cli).with_file_name("treemanip-server"),
        // A bench: the binaries of its profile sit beside the bench's
        // own executable's folder.
        (None, None) => std::env::current_exe()
            .unwrap()
            .parent()
            .and_then(|deps| deps.parent())
            .unwrap()
            .join("treemanip-server"),
    };
    assert!(
        exe.is_file(),
        "{} is not built: run the tests with --workspace, or `cargo build --bin treemanip-server` (add --release for the benches)",
        exe.display()
    );
    exe
}

/// The workspace's root: where `models/` and `robots/` are, and where the
/// server is started (its defaults and the tests' paths are relative to it).
pub fn workspace_root() -> &'static std::path::Path {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .find(|d| d.join("Cargo.lock").is_file())
        .expect("the workspace root holds Cargo.lock")
}

pub struct Server {
    pub child: Child,
    pub addr: String,
    agent: ureq::Agent,
}

/// A client that hands back every status (4xx and 5xx are answers here,
/// not errors) and gives up after 30 s.
pub fn client() -> ureq::Agent {
    agent(10)
}

/// An agent keeping at most `pooled` idle connections. A test's own agent
/// keeps none: a server may close a keep-alive connection after an answer
/// it gave before reading the request body (a 415, a panic), and a request
/// sent on that connection would fail with "peer disconnected" depending on
/// timing. Each request on its own connection tests what the test means to.
fn agent(pooled: usize) -> ureq::Agent {
    ureq::Agent::config_builder()
        .http_status_as_error(false)
        .timeout_global(Some(Duration::from_secs(30)))
        .max_idle_connections(pooled)
        .max_idle_connections_per_host(pooled)
        .build()
        .into()
}

impl Server {
    /// Starts the server on a free loopback port with extra `args`.
    pub fn start(args: &[&str]) -> Self {
        let mut child = Command::new(server_exe())
            .current_dir(workspace_root())
            .args(["--bind", "127.0.0.1:0"])
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("server starts");
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        let addr = line
            .trim()
            .strip_prefix("listening on http://")
            .unwrap_or_else(|| panic!("unexpected first line: {line:?}"))
            .to_owned();
        Self {
            child,
            addr,
            agent: agent(0),
        }
    }

    /// Sends one request; returns status, the lower-cased header block and
    /// the body.
    pub fn request(
        &self,
        method: &str,
        path: &str,
        content_type: &str,
        body: &[u8],
    ) -> (u16, String, String) {
        let request = ureq::http::Request::builder()
            .method(method)
            .uri(format!("http://{}{path}", self.addr))
            .header("content-type", content_type)
            .body(body.to_vec())
            .unwrap();
        let mut response = self
            .agent
            .run(request)
            .unwrap_or_else(|e| panic!("{method} {path}: {e}"));
        let head: String = response
            .headers()
            .iter()
            .map(|(k, v)| format!("{}: {}\r\n", k, v.to_str().unwrap_or("")))
            .collect();
        let text = response
            .body_mut()
            .with_config()
            .limit(64 << 20)
            .read_to_string()
            .unwrap();
        (response.status().as_u16(), head.to_ascii_lowercase(), text)
    }

    /// Writes one HTTP/1.1 request on a bare socket; returns status,
    /// lower-cased headers and body. For what a client library would not
    /// send or would give up on: a body the server refuses before reading
    /// it all.
    pub fn raw(
        &self,
        method: &str,
        path: &str,
        content_type: &str,
        body: &[u8],
    ) -> (u16, String, String) {
        let mut stream = TcpStream::connect(&self.addr).unwrap();
        stream
            .set_read_timeout(Some(Duration::from_secs(30)))
            .unwrap();
        write!(
            stream,
            "{method} {path} HTTP/1.1\r\nHost: test\r\nConnection: close\r\nContent-Type: {content_type}\r\nContent-Length: {}\r\n\r\n",
            body.len()
        )
        .unwrap();
        // The server may answer (413) before it has read a large body.
        let _ = stream.write_all(body);
        let mut response = Vec::new();
        let _ = stream.read_to_end(&mut response);
        let response = String::from_utf8_lossy(&response).into_owned();
        let (head, body) = response.split_once("\r\n\r\n").expect("header/body split");
        let status = head.split_whitespace().nth(1).unwrap().parse().unwrap();
        (status, head.to_ascii_lowercase(), body.to_owned())
    }

    /// A GET expecting JSON.
    pub fn get(&self, path: &str) -> (u16, Value) {
        self.send("GET", path, "application/json", b"")
    }

    /// A request with a JSON body, expecting a JSON answer.
    pub fn json(&self, method: &str, path: &str, body: &Value) -> (u16, Value) {
        self.send(
            method,
            path,
            "application/json",
            &serde_json::to_vec(body).unwrap(),
        )
    }

    pub fn send(&self, method: &str, path: &str, content_type: &str, body: &[u8]) -> (u16, Value) {
        let (status, head, body) = self.request(method, path, content_type, body);
        assert!(head.contains("content-type: application/json"), "{head}");
        (
            status,
            serde_json::from_str(&body).unwrap_or_else(|e| panic!("{e}: {body}")),
        )
    }
}

impl Server {
    pub fn terminate(&self) {
        let pid = self.child.id().to_string();
        assert!(
            Command::new("kill")
                .args(["-TERM", &pid])
                .status()
                .unwrap()
                .success()
        );
    }

    /// Waits (up to 10 s) for the process to exit, and asserts it exited 0.
    pub fn wait_for_clean_exit(&mut self, what: &str) {
        let deadline = std::time::Instant::now() + Duration::from_secs(10);
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                assert!(status.success(), "exit status {status}");
                return;
            }
            assert!(std::time::Instant::now() < deadline, "{what}");
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
    }
}
