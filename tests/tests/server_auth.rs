//! Bearer tokens on both APIs: without a token writes are UNAUTHENTICATED / 401, with a read
//! token PERMISSION_DENIED / 403, with a write token they succeed and leave an audit line;
//! and ecatd refuses a non-loopback address without tokens.

mod server_support;

use server_support::{Ecatd, call, curl, run_to_exit};

const CONFIG: &str = r#"
[[tokens]]
name = "viewer"
token = "read-secret-1-viewer"
role = "read"

[[tokens]]
name = "engineer"
token = "write-secret-2-engineer"
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
    let (status, body) = put(Some("read-secret-1-viewer"));
    assert_eq!(status, 403, "{body}");
    assert!(body.contains("permission_denied"), "{body}");
    assert_eq!(put(Some("write-secret-2-engineer")).0, 200);
    // Reads: a read token is enough, no token is not.
    assert_eq!(curl(&["-s", &url]).0, 401);
    let (status, body) = curl(&[
        "-s",
        "-H",
        "authorization: Bearer read-secret-1-viewer",
        &url,
    ]);
    assert_eq!(status, 200);
    assert!(body.contains("01020304"), "the write took effect: {body}");
    // Stopping the gateway is a write too.
    let stop = format!("{}/api/v1/gateway/stop", ecatd.http);
    let post = |token: &str| {
        let header = format!("authorization: Bearer {token}");
        curl(&["-s", "-X", "POST", "-H", &header, &stop])
    };
    assert_eq!(curl(&["-s", "-X", "POST", &stop]).0, 401);
    assert_eq!(post("read-secret-1-viewer").0, 403);
    let (status, body) = post("write-secret-2-engineer");
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
        download(&["authorization: Bearer read-secret-1-viewer"])
            .unwrap_err()
            .0,
        "7",
        "PERMISSION_DENIED"
    );
    download(&["authorization: Bearer write-secret-2-engineer"]).unwrap();
    let upload = call(
        &ecatd.grpc,
        &["authorization: Bearer read-secret-1-viewer"],
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
        stop(&["authorization: Bearer read-secret-1-viewer"])
            .unwrap_err()
            .0,
        "7",
        "PERMISSION_DENIED"
    );
    let stopped = stop(&["authorization: Bearer write-secret-2-engineer"]).unwrap();
    assert!(stopped["running"].is_null(), "stopped: {stopped}");
    let status = call(
        &ecatd.grpc,
        &["authorization: Bearer read-secret-1-viewer"],
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

fn config_file(name: &str, toml: &str) -> std::path::PathBuf {
    let file = std::env::temp_dir().join(format!("ecatd-auth-{name}-{}.toml", std::process::id()));
    std::fs::write(&file, toml).unwrap();
    file
}

#[test]
fn empty_or_short_tokens_are_refused_by_name() {
    for (secret, what) in [("", "empty"), ("short-secret", "too short")] {
        let file = config_file(
            "short",
            &format!("[[tokens]]\nname = \"ops-team\"\ntoken = \"{secret}\"\nrole = \"read\"\n"),
        );
        let (status, stderr) = run_to_exit(&["--simulate", "--config", file.to_str().unwrap()]);
        std::fs::remove_file(file).unwrap();
        assert!(!status.success());
        assert!(
            stderr.contains("\"ops-team\"") && stderr.contains(what),
            "{stderr}"
        );
        assert!(secret.is_empty() || !stderr.contains(secret), "{stderr}");
    }
}

#[test]
fn tokens_off_loopback_need_tls_or_insecure() {
    let file = config_file("clear", CONFIG);
    let path = file.to_str().unwrap();
    let args = [
        "--simulate",
        "--config",
        path,
        "--grpc-listen",
        "127.0.0.1:0",
        "--http-listen",
        "0.0.0.0:0",
    ];
    let (status, stderr) = run_to_exit(&args);
    assert!(!status.success());
    assert!(
        stderr.contains("clear text") && stderr.contains("[tls]") && stderr.contains("--insecure"),
        "{stderr}"
    );
    // With --insecure it starts (tokens still required).
    let ecatd = Ecatd::start(&["--config", path, "--insecure"]);
    std::fs::remove_file(&file).unwrap();
    assert_eq!(
        curl(&["-s", &format!("{}/api/v1/slaves", ecatd.http)]).0,
        401
    );
}

#[test]
fn secret_files_reload_on_sighup_and_a_bad_reload_keeps_the_old_set() {
    let secret = std::env::temp_dir().join(format!("ecatd-auth-secret-{}", std::process::id()));
    std::fs::write(&secret, "first-secret-from-a-file\n").unwrap();
    let file = config_file(
        "reload",
        &format!(
            "metrics_token = true\n[[tokens]]\nname = \"viewer\"\nsecret_file = {:?}\nrole = \"read\"\n",
            secret.to_str().unwrap()
        ),
    );
    let ecatd = Ecatd::start(&["--config", file.to_str().unwrap()]);
    let url = format!("{}/api/v1/slaves", ecatd.http);
    let get =
        |secret: &str| curl(&["-s", "-H", &format!("authorization: Bearer {secret}"), &url]).0;
    assert_eq!(get("first-secret-from-a-file"), 200);
    let hangup = || {
        let status = std::process::Command::new("kill")
            .args(["-HUP", &ecatd.pid().to_string()])
            .status()
            .unwrap();
        assert!(status.success());
    };
    let until = |done: &dyn Fn() -> bool| {
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
        while !done() {
            assert!(std::time::Instant::now() < deadline, "{}", ecatd.log());
            // Poll interval; the loop ends on the condition or the deadline.
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
    };
    std::fs::write(&secret, "second-secret-from-a-file\n").unwrap();
    hangup();
    until(&|| get("second-secret-from-a-file") == 200);
    assert_eq!(get("first-secret-from-a-file"), 401);
    // A short secret does not pass: the old set stays, the log says why.
    std::fs::write(&secret, "short\n").unwrap();
    hangup();
    until(&|| ecatd.log().contains("tokens not reloaded"));
    assert!(ecatd.log().contains("too short"), "{}", ecatd.log());
    assert_eq!(get("second-secret-from-a-file"), 200);
    // The bus was not touched: the slaves are still there and in OP.
    let (status, body) = curl(&[
        "-s",
        "-H",
        "authorization: Bearer second-secret-from-a-file",
        &url,
    ]);
    assert_eq!(status, 200);
    let slaves: serde_json::Value = serde_json::from_str(&body).unwrap();
    let states: Vec<&serde_json::Value> = slaves
        .as_array()
        .unwrap()
        .iter()
        .map(|s| &s["state"])
        .collect();
    assert!(
        !states.is_empty() && states.iter().all(|s| *s == "OP"),
        "{body}"
    );
    // `metrics_token = true`: /metrics needs a token, a read one will do.
    let metrics = format!("{}/metrics", ecatd.http);
    assert_eq!(curl(&["-s", &metrics]).0, 401);
    let (status, text) = curl(&[
        "-s",
        "-H",
        "authorization: Bearer second-secret-from-a-file",
        &metrics,
    ]);
    assert_eq!(status, 200);
    assert!(text.contains("ecat_"), "{text}");
    std::fs::remove_file(file).unwrap();
    std::fs::remove_file(secret).unwrap();
}

#[test]
fn metrics_stay_open_without_the_switch() {
    let (ecatd, file) = start();
    std::fs::remove_file(file).unwrap();
    assert_eq!(curl(&["-s", &format!("{}/metrics", ecatd.http)]).0, 200);
}
