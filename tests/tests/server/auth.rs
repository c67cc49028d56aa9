//! Bearer tokens on both APIs: without a token writes are UNAUTHENTICATED / 401, with a read
//! token PERMISSION_DENIED / 403, with a write token they succeed and leave an audit line;
//! and ecatd refuses a non-loopback address without tokens.

use crate::server_support;

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

/// The outcome of one REST call with `token`: the HTTP status and the body.
fn rest_call(method: &str, url: &str, token: Option<&str>) -> (u16, String) {
    let header = token.map(|t| format!("authorization: Bearer {t}"));
    // A stream (the events route) is cut after 2 s: its status is known by then.
    let mut args = vec!["-s", "-m", "2", "-X", method];
    if method != "GET" {
        args.extend(["-H", "content-type: application/json", "-d", "{}"]);
    }
    if let Some(h) = &header {
        args.extend(["-H", h.as_str()]);
    }
    args.push(url);
    curl(&args)
}

/// The operation a refusal names: the core says "`<operation>` needs a write token".
fn refused_operation(text: &str) -> Option<String> {
    let name = text.split(" needs a write token").next()?;
    let name = name.rsplit(['"', ' ', ':']).next()?;
    text.contains(" needs a write token")
        .then(|| name.to_owned())
}

/// The operations that need the write role and have a route on both APIs: every one the core
/// declares but the register read over a mailbox area (a read route; the core decides by
/// the address, `a_mailbox_area_read_needs_a_write_token`) and the simulator's emergency
/// and ring cuts (`--simulate` only, not in the API documents).
fn operations_with_routes() -> std::collections::BTreeSet<String> {
    use server::service::Operation;
    Operation::ALL
        .iter()
        .filter(|op| {
            !matches!(
                op,
                Operation::ReadRegisterWithEffect | Operation::SimEmergency | Operation::SimRing
            )
        })
        .map(|op| op.name().to_owned())
        .collect()
}

/// Every route of the OpenAPI document ecatd serves, and the public ones, with no, a read and
/// a write token. Without a token every API route is 401 and a public one open; with a read
/// token the core refuses exactly the routes of the operations it declares as writes (each
/// route its own operation, named in the refusal), every route whose method is not GET among
/// them; a write token is refused nowhere.
#[test]
fn every_route_is_admitted_by_the_core() {
    let (ecatd, file) = start();
    std::fs::remove_file(file).unwrap();
    let (status, text) = curl(&["-s", &format!("{}/api/v1/openapi.json", ecatd.http)]);
    assert_eq!(status, 200, "{text}");
    let document: serde_json::Value = serde_json::from_str(&text).unwrap();
    let mut routes = Vec::new();
    for (path, item) in document["paths"].as_object().expect("paths") {
        let full = if path.starts_with("/api/v1") {
            path.clone()
        } else {
            format!("/api/v1{path}")
        };
        for method in item.as_object().unwrap().keys() {
            routes.push((method.to_ascii_uppercase(), full.clone()));
        }
    }
    assert!(routes.len() >= 25, "the document lists the API: {routes:?}");
    let mut refused = std::collections::BTreeMap::new();
    for (method, path) in &routes {
        // A slave that does not exist and placeholder arguments: the core admits before
        // anything is read, and a write token's call fails on its arguments.
        let mut concrete = path.replace("{slave}", "999");
        while let Some(open) = concrete.find('{') {
            let close = concrete[open..].find('}').unwrap() + open;
            concrete.replace_range(open..=close, "1");
        }
        let url = format!("{}{concrete}", ecatd.http);
        let none = rest_call(method, &url, None).0;
        let (read, read_body) = rest_call(method, &url, Some("read-secret-1-viewer"));
        let write = rest_call(method, &url, Some("write-secret-2-engineer")).0;
        let context =
            format!("{method} {path}: none {none}, read {read} {read_body}, write {write}");
        assert_eq!(none, 401, "{context}");
        assert!(![0, 401, 403].contains(&write), "{context}");
        if read == 403 {
            let body: serde_json::Value = serde_json::from_str(&read_body).unwrap();
            assert_eq!(
                body["type"], "urn:ecat:error:permission_denied",
                "{context}"
            );
            let operation = refused_operation(body["detail"].as_str().unwrap())
                .unwrap_or_else(|| panic!("the refusal names no operation: {context}"));
            let before = refused.insert(operation.clone(), format!("{method} {path}"));
            assert!(
                before.is_none(),
                "{operation} has two routes: {before:?}, {context}"
            );
        } else {
            assert!(![0, 401].contains(&read), "{context}");
            assert_eq!(
                method, "GET",
                "a read token passed a route that changes: {context}"
            );
        }
    }
    let names: std::collections::BTreeSet<String> = refused.keys().cloned().collect();
    assert_eq!(
        names,
        operations_with_routes(),
        "routes refused: {refused:#?}"
    );
    for path in [
        "/healthz",
        "/readyz",
        "/metrics",
        "/",
        "/static/app.js",
        "/api/v1/openapi.json",
    ] {
        let none = rest_call("GET", &format!("{}{path}", ecatd.http), None).0;
        assert!(![0, 401, 403].contains(&none), "GET {path}: {none}");
    }
}

/// The gRPC status code (`"0"` for success) and message of calling `method`
/// (`/package.Service/Method`) with `token` and an empty message.
fn grpc_call(addr: &str, method: &str, token: Option<&str>) -> (String, String) {
    let header = token.map(|t| format!("authorization: Bearer {t}"));
    let mut command = std::process::Command::new(server_support::grpcurl_path());
    // Streams (events, health watch) are cut after 2 s.
    command.args(["-plaintext", "-format-error", "-max-time", "2", "-d", "{}"]);
    if let Some(h) = &header {
        command.args(["-H", h]);
    }
    let output = command
        .arg(addr)
        .arg(method.trim_start_matches('/'))
        .output()
        .expect("grpcurl runs");
    if output.status.success() {
        return ("0".into(), String::new());
    }
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    serde_json::Deserializer::from_str(&stderr)
        .into_iter::<serde_json::Value>()
        .next()
        .and_then(Result::ok)
        .and_then(|status| {
            let code = status["code"].as_u64()?.to_string();
            Some((code, status["message"].as_str().unwrap_or("").to_owned()))
        })
        .unwrap_or_else(|| (format!("? {stderr}"), String::new()))
}

/// Every gRPC method reflection lists, with no, a read and a write token: the public ones
/// (health, reflection) open to all; every other one UNAUTHENTICATED (16) without a token;
/// with a read token PERMISSION_DENIED (7) exactly on the operations the core declares as
/// writes, named in the refusal; a write token refused nowhere.
#[test]
fn every_grpc_method_is_admitted_by_the_core() {
    let (ecatd, file) = start();
    std::fs::remove_file(file).unwrap();
    let mut methods = Vec::new();
    for service in server_support::grpcurl(&[&ecatd.grpc, "list"]).lines() {
        let service = service.trim();
        if service.is_empty() {
            continue;
        }
        for line in server_support::grpcurl(&[&ecatd.grpc, "describe", service]).lines() {
            let Some(rest) = line.trim().strip_prefix("rpc ") else {
                continue;
            };
            let name = rest.split([' ', '(']).next().unwrap();
            methods.push(format!("/{service}/{name}"));
        }
    }
    assert!(methods.len() >= 28, "reflection lists the API: {methods:?}");
    let mut refused = std::collections::BTreeMap::<String, Vec<String>>::new();
    let refusal = |code: &str| ["16", "7"].contains(&code) || code.starts_with('?');
    for path in &methods {
        let public = path.starts_with("/grpc.");
        let none = grpc_call(&ecatd.grpc, path, None).0;
        let (read, message) = grpc_call(&ecatd.grpc, path, Some("read-secret-1-viewer"));
        let write = grpc_call(&ecatd.grpc, path, Some("write-secret-2-engineer")).0;
        let context = format!("{path}: none {none}, read {read} {message}, write {write}");
        assert!(!refusal(&write), "{context}");
        if public {
            assert!(!refusal(&none) && !refusal(&read), "{context}");
            continue;
        }
        assert_eq!(none, "16", "{context}");
        if read == "7" {
            let operation = refused_operation(&message)
                .unwrap_or_else(|| panic!("the refusal names no operation: {context}"));
            refused.entry(operation).or_default().push(path.clone());
        } else {
            assert!(!refusal(&read), "{context}");
        }
    }
    let names: std::collections::BTreeSet<String> = refused.keys().cloned().collect();
    assert_eq!(
        names,
        operations_with_routes(),
        "methods refused: {refused:#?}"
    );
    // One operation, two methods: FoE Write and its progress form.
    assert_eq!(refused["foe_write"].len(), 2, "{refused:#?}");
    assert!(
        refused.values().filter(|m| m.len() > 1).count() == 1,
        "{refused:#?}"
    );
}

/// A register read over the drive's SM1 mailbox buffer (at the start address its SM1
/// register holds) needs a write token on both APIs; other registers a read token reads.
#[test]
fn a_mailbox_area_read_needs_a_write_token() {
    let (ecatd, file) = start();
    std::fs::remove_file(file).unwrap();
    let read_as = |token: &str, address: u16, length: usize| {
        let header = format!("authorization: Bearer {token}");
        let url = format!(
            "{}/api/v1/slaves/3/registers/0x{address:04X}?length={length}",
            ecatd.http
        );
        curl(&["-s", "-H", &header, &url])
    };
    // SM1's configuration (ETG.1000.4 §6.7, Table 59): start address and length, u16 LE.
    let (status, body) = read_as("read-secret-1-viewer", 0x0808, 4);
    assert_eq!(status, 200, "SM registers are plain reads: {body}");
    let value: serde_json::Value = serde_json::from_str(&body).unwrap();
    let hex = value["data"].as_str().unwrap();
    let bytes: Vec<u8> = (0..hex.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&hex[i..i + 2], 16).unwrap())
        .collect();
    let start = u16::from_le_bytes([bytes[0], bytes[1]]);
    let len = u16::from_le_bytes([bytes[2], bytes[3]]);
    assert!(start >= 0x1000 && len > 0, "the drive has a mailbox: {hex}");

    let (status, body) = read_as("read-secret-1-viewer", start, 1);
    assert_eq!(status, 403, "{body}");
    assert!(body.contains("permission_denied"), "{body}");
    // Overlapping the area from below counts too.
    assert_eq!(read_as("read-secret-1-viewer", start - 2, 4).0, 403);
    assert_eq!(
        read_as("read-secret-1-viewer", 0x0130, 2).0,
        200,
        "AL status"
    );
    // A write token's read reaches the slave: an empty send mailbox does not answer a read
    // of its buffer (working counter 0, ETG.1000.4 §6.7), a full one hands its data over.
    let (status, body) = read_as("write-secret-2-engineer", start, 1);
    assert!(
        status == 200 || (status == 503 && body.contains("working counter 0")),
        "{status} {body}"
    );

    let grpc_read = |token: &str, address: u16| {
        call(
            &ecatd.grpc,
            &[&format!("authorization: Bearer {token}")],
            "ecat.v1.BusService/ReadRegister",
            &format!(r#"{{"slave":"3","address":{address},"length":1}}"#),
        )
    };
    assert_eq!(
        grpc_read("read-secret-1-viewer", start).unwrap_err().0,
        "7",
        "PERMISSION_DENIED"
    );
    grpc_read("read-secret-1-viewer", 0x0130).unwrap();
    match grpc_read("write-secret-2-engineer", start) {
        Ok(_) => {}
        Err((code, message)) => assert!(
            code == "14" && message.contains("working counter 0"),
            "{code} {message}"
        ),
    }
    let log = ecatd.log();
    assert!(
        log.lines().any(|l| l.contains("\"target\":\"audit\"")
            && l.contains("viewer")
            && l.contains("SM1")),
        "no audit line for the refused read:\n{log}"
    );
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

/// A caller without a token is refused before its body is read: a body above the 16 MiB
/// limit gets 401 (the token check), not 413 (which reading it would give), so an
/// unauthenticated client cannot make ecatd buffer bodies.
#[test]
fn an_unauthenticated_body_is_never_read() {
    let (ecatd, file) = start();
    std::fs::remove_file(file).unwrap();
    let body = std::env::temp_dir().join(format!("ecatd-auth-body-{}", std::process::id()));
    std::fs::write(&body, vec![0u8; 17 << 20]).unwrap();
    let url = format!("{}/api/v1/slaves/0/coe/sdo/0x2000/0", ecatd.http);
    let upload = format!("@{}", body.to_str().unwrap());
    let args = [
        "-s",
        "-X",
        "PUT",
        "-H",
        "content-type: application/octet-stream",
        "--data-binary",
        upload.as_str(),
        url.as_str(),
    ];
    let (status, text) = curl(&args);
    std::fs::remove_file(&body).unwrap();
    // Refused without reading it: by the body limit from its Content-Length (outermost,
    // docs/configuration.md, [limits]) or by the missing token; never read and then judged.
    assert!(status == 413 || status == 401, "{status}: {text}");
}
