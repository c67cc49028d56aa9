//! TLS: ecatd started with a certificate signed by a CA the test makes (rcgen) serves gRPC
//! and HTTP over TLS. `ecat --tls-ca` lists the slaves over gRPC, `curl --cacert` reads a
//! REST route; plain HTTP to the TLS port, and TLS without trusting the CA, get nothing.
//! SIGHUP swaps the certificate for new connections on both ports; a bad one is refused.

use crate::server_support;

use std::path::PathBuf;
use std::process::Command;
use std::time::{Duration, Instant};

use rcgen::{BasicConstraints, CertificateParams, CertifiedIssuer, DnType, IsCa, KeyPair};
use server_support::{Ecatd, bin_dir, curl};
use sim::topology::Topology;

/// A directory of PEM files, removed on drop.
struct Pki {
    dir: PathBuf,
    ca: CertifiedIssuer<'static, KeyPair>,
}

impl Pki {
    /// A CA and a server certificate for `localhost` and 127.0.0.1 signed by it.
    fn new(tag: &str) -> Pki {
        let dir = std::env::temp_dir().join(format!("ecatd-tls-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut ca_params = CertificateParams::new(Vec::<String>::new()).unwrap();
        ca_params.is_ca = IsCa::Ca(BasicConstraints::Unconstrained);
        ca_params
            .distinguished_name
            .push(DnType::CommonName, "ecatd test CA");
        let ca = CertifiedIssuer::self_signed(ca_params, KeyPair::generate().unwrap()).unwrap();
        std::fs::write(dir.join("ca.pem"), ca.pem()).unwrap();
        let pki = Pki { dir, ca };
        pki.issue("cert.pem", "key.pem", "ecatd test server");
        pki
    }

    /// A server certificate for `localhost` and 127.0.0.1 named `name`, signed by the CA,
    /// written to `cert` and `key`; returns its SHA-256 fingerprint as openssl prints it.
    fn issue(&self, cert: &str, key: &str, name: &str) -> String {
        let pair = KeyPair::generate().unwrap();
        let mut params =
            CertificateParams::new(vec!["localhost".to_owned(), "127.0.0.1".to_owned()]).unwrap();
        params.distinguished_name.push(DnType::CommonName, name);
        let signed = params.signed_by(&pair, &self.ca).unwrap();
        std::fs::write(self.dir.join(cert), signed.pem()).unwrap();
        std::fs::write(self.dir.join(key), pair.serialize_pem()).unwrap();
        fingerprint(signed.pem().as_bytes())
    }

    fn path(&self, name: &str) -> String {
        self.dir.join(name).to_str().unwrap().to_owned()
    }
}

impl Drop for Pki {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// The SHA-256 fingerprint of the first certificate in `pem`, as `openssl x509` prints it.
fn fingerprint(pem: &[u8]) -> String {
    use std::io::Write;
    let mut child = Command::new("openssl")
        .args(["x509", "-noout", "-fingerprint", "-sha256"])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("openssl runs");
    child.stdin.take().unwrap().write_all(pem).unwrap();
    let output = child.wait_with_output().unwrap();
    assert!(output.status.success(), "openssl x509 failed on {pem:?}");
    String::from_utf8_lossy(&output.stdout).trim().to_owned()
}

/// The fingerprint of the certificate a new TLS connection to `addr` (`host:port`) is
/// shown, offering `alpn`.
fn served_fingerprint(addr: &str, alpn: &str) -> String {
    let output = Command::new("openssl")
        .args(["s_client", "-connect", addr, "-servername", "localhost"])
        .args(["-alpn", alpn])
        .stdin(std::process::Stdio::null())
        .output()
        .expect("openssl runs");
    fingerprint(&output.stdout)
}

fn ecat(args: &[&str]) -> std::process::Output {
    Command::new(bin_dir().join("ecat"))
        .args(args)
        .output()
        .expect("ecat runs")
}

#[test]
fn both_apis_speak_tls_and_only_tls() {
    let pki = Pki::new("apis");
    let ecatd = Ecatd::start(&[
        "--tls-cert",
        &pki.path("cert.pem"),
        "--tls-key",
        &pki.path("key.pem"),
    ]);
    let slaves = Topology::default_segment().slaves.len();
    assert!(ecatd.http.starts_with("https://"), "{}", ecatd.http);
    let ca = pki.path("ca.pem");

    // gRPC through ecat, trusting the CA.
    let address = format!("https://{}", ecatd.grpc);
    let output = ecat(&["--address", &address, "--tls-ca", &ca, "--json", "slaves"]);
    assert!(
        output.status.success(),
        "ecat over TLS failed:\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let listed: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(listed.as_array().map(Vec::len), Some(slaves), "{listed}");

    // REST through curl, trusting the CA.
    let url = format!("{}/api/v1/slaves", ecatd.http);
    let (status, body) = curl(&["-s", "--cacert", &ca, &url]);
    assert_eq!(status, 200, "{body}");
    let listed: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert_eq!(listed.as_array().map(Vec::len), Some(slaves));

    // Plain HTTP to the TLS port: no HTTP answer at all.
    let plain = url.replacen("https://", "http://", 1);
    let (status, _) = curl(&["-s", &plain]);
    assert_eq!(status, 0, "plain HTTP got an HTTP answer");
    // TLS without trusting the CA: refused by curl's verification.
    let (status, _) = curl(&["-s", &url]);
    assert_eq!(status, 0, "an untrusted certificate was accepted");
    // gRPC in plain text to the TLS port fails.
    let output = ecat(&["--address", &format!("http://{}", ecatd.grpc), "slaves"]);
    assert!(
        !output.status.success(),
        "plain gRPC to the TLS port worked"
    );
    // The API is still up after the bad clients.
    let (status, _) = curl(&["-s", "--cacert", &ca, &url]);
    assert_eq!(status, 200);
}

#[test]
fn a_missing_key_refuses_the_start() {
    let pki = Pki::new("missing");
    let (status, stderr) = server_support::run_to_exit(&[
        "--simulate",
        "--grpc-listen",
        "127.0.0.1:0",
        "--http-listen",
        "127.0.0.1:0",
        "--no-gateway",
        "--tls-cert",
        &pki.path("cert.pem"),
        "--tls-key",
        &pki.path("missing.pem"),
    ]);
    assert!(!status.success());
    assert!(stderr.contains("TLS key"), "{stderr}");
}

#[test]
fn sighup_reloads_the_certificate_and_refuses_a_bad_one() {
    let pki = Pki::new("reload");
    let first = fingerprint(&std::fs::read(pki.dir.join("cert.pem")).unwrap());
    let ecatd = Ecatd::start(&[
        "--tls-cert",
        &pki.path("cert.pem"),
        "--tls-key",
        &pki.path("key.pem"),
    ]);
    let http = ecatd.http.trim_start_matches("https://").to_owned();
    let ports = [(ecatd.grpc.as_str(), "h2"), (http.as_str(), "http/1.1")];
    for (addr, alpn) in ports {
        assert_eq!(served_fingerprint(addr, alpn), first, "{addr}");
    }
    // A connection made before the reloads, used again after them.
    let mut kept = KeptConnection::open(&http);
    kept.get_health(1);
    let hangup = || {
        // SAFETY: `kill` on ecatd, our own child, which is still running.
        let sent = unsafe { libc::kill(ecatd.pid() as libc::pid_t, libc::SIGHUP) };
        assert_eq!(sent, 0);
    };
    let wait_log = |line: &str, times: usize| {
        let deadline = Instant::now() + Duration::from_secs(10);
        while ecatd.log().matches(line).count() < times {
            assert!(Instant::now() < deadline, "no {line:?}:\n{}", ecatd.log());
            // Poll interval of the log check; the loop ends on the line or the deadline.
            std::thread::sleep(Duration::from_millis(20));
        }
    };

    // A certificate whose key belongs to another one: refused, the first one stays.
    let other = pki.issue("other.pem", "other-key.pem", "ecatd other server");
    std::fs::copy(pki.dir.join("other.pem"), pki.dir.join("cert.pem")).unwrap();
    hangup();
    wait_log("SIGHUP: TLS certificate not reloaded", 1);
    for (addr, alpn) in ports {
        assert_eq!(served_fingerprint(addr, alpn), first, "{addr}");
    }
    assert_ne!(other, first);

    // A new pair: new connections on both ports see it.
    let second = pki.issue("cert.pem", "key.pem", "ecatd second server");
    hangup();
    wait_log("SIGHUP: TLS certificate reloaded", 1);
    for (addr, alpn) in ports {
        assert_eq!(served_fingerprint(addr, alpn), second, "{addr}");
    }
    // The connection made with the first certificate was not dropped.
    kept.get_health(2);
    // And they still work as APIs, trusting the same CA.
    let url = format!("{}/api/v1/slaves", ecatd.http);
    let (status, body) = curl(&["-s", "--cacert", &pki.path("ca.pem"), &url]);
    assert_eq!(status, 200, "{body}");
    let address = format!("https://{}", ecatd.grpc);
    let output = ecat(&[
        "--address",
        &address,
        "--tls-ca",
        &pki.path("ca.pem"),
        "slaves",
    ]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
}

/// One HTTP/1.1 connection over TLS (`openssl s_client`), kept open across requests.
struct KeptConnection {
    child: std::process::Child,
    output: std::sync::Arc<std::sync::Mutex<String>>,
}

impl KeptConnection {
    fn open(addr: &str) -> KeptConnection {
        use std::io::Read;
        let mut child = Command::new("openssl")
            .args([
                "s_client",
                "-quiet",
                "-connect",
                addr,
                "-servername",
                "localhost",
            ])
            .args(["-alpn", "http/1.1"])
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("openssl runs");
        let mut stdout = child.stdout.take().unwrap();
        let output = std::sync::Arc::new(std::sync::Mutex::new(String::new()));
        let keep = std::sync::Arc::clone(&output);
        std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n) = stdout.read(&mut buf) {
                if n == 0 {
                    break;
                }
                keep.lock()
                    .unwrap()
                    .push_str(&String::from_utf8_lossy(&buf[..n]));
            }
        });
        KeptConnection { child, output }
    }

    /// Sends `GET /healthz` on the connection and waits for the `nth` 200 answer on it.
    fn get_health(&mut self, nth: usize) {
        use std::io::Write;
        let stdin = self.child.stdin.as_mut().unwrap();
        stdin
            .write_all(b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
            .unwrap();
        stdin.flush().unwrap();
        let deadline = Instant::now() + Duration::from_secs(10);
        while self.output.lock().unwrap().matches("HTTP/1.1 200").count() < nth {
            assert!(
                Instant::now() < deadline,
                "no answer {nth} on the kept connection: {:?}",
                self.output.lock().unwrap()
            );
            assert!(
                self.child.try_wait().unwrap().is_none(),
                "the kept connection was closed: {:?}",
                self.output.lock().unwrap()
            );
            // Poll interval of the answer check; the loop ends on the answer or the deadline.
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for KeptConnection {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
