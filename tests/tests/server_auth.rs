//! Bearer tokens on both APIs: without a token writes are UNAUTHENTICATED / 401, with a read
//! token PERMISSION_DENIED / 403, with a write token they succeed and leave an audit line;
//! and ecatd refuses a non-loopback address without tokens.

mod server_support;

use server_support::{Ecatd, call, curl, run_to_exit};

const CONFIG: &str = r#"
[[tokens]]
name = "viewer"
token = "read-secret-1"
role = "read"

[[tokens]]
name = "engineer"
token = "write-secret-2"
role = "write"
"#;

fn start() -> (Ecatd, std::path::PathBuf) {
    let file = std::env::temp_dir().join(format!(
        "ecatd-auth-{}-{:?}.toml",
        std::process::id(),
        std::thread::current().id()
    ));
    std::fs::write(&file, CONFIG).unwrap();
    let ecatd = Ecatd::start(&["--config", file.to_str().unwrap()]);
    (ecatd, file)
}

#[test]
fn rest_writes_need_a_write_token() {
    let (ecatd, file) = start();
    std::fs::remove_file(file).unwrap();
    let url = format!("{}/api/v1/slaves/3/coe/sdo/0x2001/0", ecatd.http);
    let put = |token: Option<&str>| {
        let header = token.map(|t| format!("authorization: Bearer {t}"));
        let mut args = vec![
            "-s",
            "-X",
            "PUT",
            "-H",
            "content-type: application/json",
            "-d",
            r#"{"data":"01020304"}"#,
        ];
        if let Some(h) = &header {
            args.extend(["-H", h.as_str()]);
        }
        args.push(&url);
        curl(&args)
    };
    assert_eq!(put(None).0, 401);
    assert_eq!(put(Some("wrong")).0, 401);
    let (status, body) = put(Some("read-secret-1"));
    assert_eq!(status, 403, "{body}");
    assert!(body.contains("permission_denied"), "{body}");
    assert_eq!(put(Some("write-secret-2")).0, 200);
    // Reads: a read token is enough, no token is not.
    assert_eq!(curl(&["-s", &url]).0, 401);
    let (status, body) = curl(&["-s", "-H", "authorization: Bearer read-secret-1", &url]);
    assert_eq!(status, 200);
    assert!(body.contains("01020304"), "the write took effect: {body}");
    // Stopping the gateway is a write too.
    let stop = format!("{}/api/v1/gateway/stop", ecatd.http);
    let post = |token: &str| {
        let header = format!("authorization: Bearer {token}");
        curl(&["-s", "-X", "POST", "-H", &header, &stop])
    };
    assert_eq!(curl(&["-s", "-X", "POST", &stop]).0, 401);
    assert_eq!(post("read-secret-1").0, 403);
    let (status, body) = post("write-secret-2");
    assert_eq!(status, 200, "{body}");
    assert!(body.contains("\"running\":false"), "{body}");
    // Health stays open for probes.
    assert_eq!(curl(&["-s", &format!("{}/readyz", ecatd.http)]).0, 200);
    let log = ecatd.log();
    assert!(
        log.lines().any(|l| l.contains("\"target\":\"audit\"")
            && l.contains("engineer")
            && l.contains("PUT /slaves/3/coe/sdo/0x2001/0")),
        "no audit line for the write:\n{log}"
    );
    assert!(
        log.lines().any(|l| l.contains("\"target\":\"audit\"")
            && l.contains("engineer")
            && l.contains("POST /gateway/stop")),
        "no audit line for the gateway stop:\n{log}"
    );
}

#[test]
fn grpc_writes_need_a_write_token() {
    let (ecatd, file) = start();
    std::fs::remove_file(file).unwrap();
    let body = r#"{"slave":"3","index":8193,"subindex":0,"data":"BQYHCA=="}"#;
    let download =
        |headers: &[&str]| call(&ecatd.grpc, headers, "ecat.v1.CoeService/Download", body);
    assert_eq!(download(&[]).unwrap_err().0, "16", "UNAUTHENTICATED");
    assert_eq!(
        download(&["authorization: Bearer read-secret-1"])
            .unwrap_err()
            .0,
        "7",
        "PERMISSION_DENIED"
    );
    download(&["authorization: Bearer write-secret-2"]).unwrap();
    let upload = call(
        &ecatd.grpc,
        &["authorization: Bearer read-secret-1"],
        "ecat.v1.CoeService/Upload",
        r#"{"slave":"3","index":8193,"subindex":0}"#,
    )
    .unwrap();
    assert_eq!(upload["data"], "BQYHCA==");
    let stop = |headers: &[&str]| {
        call(
            &ecatd.grpc,
            headers,
            "ecat.v1.GatewayService/StopGateway",
            "{}",
        )
    };
    assert_eq!(stop(&[]).unwrap_err().0, "16", "UNAUTHENTICATED");
    assert_eq!(
        stop(&["authorization: Bearer read-secret-1"])
            .unwrap_err()
            .0,
        "7",
        "PERMISSION_DENIED"
    );
    let stopped = stop(&["authorization: Bearer write-secret-2"]).unwrap();
    assert!(stopped["running"].is_null(), "stopped: {stopped}");
    let status = call(
        &ecatd.grpc,
        &["authorization: Bearer read-secret-1"],
        "ecat.v1.GatewayService/GetGateway",
        "{}",
    )
    .unwrap();
    assert_eq!(status["enabled"], true, "reading needs a read token only");
    assert!(status["running"].is_null());
    let log = ecatd.log();
    for operation in ["coe_download", "stop_gateway"] {
        assert!(
            log.lines().any(|l| l.contains("\"target\":\"audit\"")
                && l.contains("engineer")
                && l.contains(operation)),
            "no audit line for {operation}:\n{log}"
        );
    }
}

#[test]
fn non_loopback_without_tokens_is_refused() {
    let (status, stderr) = run_to_exit(&[
        "--simulate",
        "--grpc-listen",
        "127.0.0.1:0",
        "--http-listen",
        "0.0.0.0:0",
    ]);
    assert!(!status.success());
    assert!(stderr.contains("--insecure"), "{stderr}");
}
