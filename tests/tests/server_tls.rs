//! TLS: ecatd started with a certificate signed by a CA the test makes (rcgen) serves gRPC
//! and HTTP over TLS. `ecat --tls-ca` lists the slaves over gRPC, `curl --cacert` reads a
//! REST route; plain HTTP to the TLS port, and TLS without trusting the CA, get nothing.

mod server_support;

use std::path::PathBuf;
use std::process::Command;

use rcgen::{BasicConstraints, CertificateParams, CertifiedIssuer, DnType, IsCa, KeyPair};
use server_support::{Ecatd, bin_dir, curl};
use sim::topology::Topology;

/// A directory of PEM files, removed on drop.
struct Pki {
    dir: PathBuf,
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
        let key = KeyPair::generate().unwrap();
        let mut params =
            CertificateParams::new(vec!["localhost".to_owned(), "127.0.0.1".to_owned()]).unwrap();
        params
            .distinguished_name
            .push(DnType::CommonName, "ecatd test server");
        let cert = params.signed_by(&key, &ca).unwrap();
        std::fs::write(dir.join("ca.pem"), ca.pem()).unwrap();
        std::fs::write(dir.join("cert.pem"), cert.pem()).unwrap();
        std::fs::write(dir.join("key.pem"), key.serialize_pem()).unwrap();
        Pki { dir }
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
