//! The dashboard in a real browser: headless Chromium driven over WebDriver
//! (`tests/py/web_dashboard.py`, Python selenium with Debian's `chromium-driver`) against
//! `ecatd --simulate` with a read and a write token. The script acts and reports what the
//! page showed; every expected value here comes from the simulator's topology or from
//! ecatd's REST API. Screenshots of each view go to `target/web-dashboard/`.
//!
//! The process-data page (`#/process-data`) is driven from here over WebDriver directly
//! ([`Browser`]: chromedriver's W3C protocol with ureq), against an ecatd with its
//! application interface on a socket of its own: live values, the force dialog, the
//! override when a control program owns the outputs, the segment's key values. So are the
//! guardrails of issue 36 (no preselected state, a confirmation before each write, the
//! read-only mode, the events filters), each checked against ecatd's own state.
//!
//! Needs `chromium`, `chromium-driver` and the venv of `scripts/test` (tests/README.md).

use crate::server_support;

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use server_support::{Ecatd, curl, root, venv_bin};
use sha2::{Digest, Sha256};
use sim::topology::{SIM_VENDOR_ID, Topology};

const READ_TOKEN: &str = "read-secret-1-dashboard";
const WRITE_TOKEN: &str = "write-secret-2-dashboard";
/// Written to 0x2001:00 (UNSIGNED32 "Parameter" of slave 3, 0x12345678 at start).
const COE_VALUE: u32 = 4660;
/// The CoE emergency the simulated drive sends (CiA 301 0x8110, CAN overrun).
const EMERGENCY_CODE: u16 = 0x8110;
/// Malformed datagrams sent to the gateway.
const BAD_REQUESTS: usize = 40;

fn config() -> std::path::PathBuf {
    let file = std::env::temp_dir().join(format!("ecatd-web-{}.toml", std::process::id()));
    std::fs::write(
        &file,
        format!(
            "[[tokens]]\nname = \"viewer\"\ntoken = \"{READ_TOKEN}\"\nrole = \"read\"\n\n\
             [[tokens]]\nname = \"engineer\"\ntoken = \"{WRITE_TOKEN}\"\nrole = \"write\"\n"
        ),
    )
    .unwrap();
    file
}

/// 1 MiB that no two runs share (the FoE store must not already hold it).
fn foe_content() -> Vec<u8> {
    let mut state = u64::from(std::process::id()) | 1;
    (0..1 << 20)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state as u8
        })
        .collect()
}

fn rest(ecatd: &Ecatd, token: &str, args: &[&str], path: &str) -> (u16, String) {
    let auth = format!("authorization: Bearer {token}");
    let url = format!("{}{path}", ecatd.http);
    let mut all = vec!["-s", "-H", auth.as_str()];
    all.extend_from_slice(args);
    all.push(&url);
    curl(&all)
}

fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

#[test]
fn the_dashboard_shows_the_segment_and_drives_the_mailboxes() {
    let _one = one_browser();
    let file = config();
    // The application interface on a socket of its own: other tests' ecatd may serve the
    // default one meanwhile.
    let sockets = std::env::temp_dir().join(format!("ecatd-web-app-{}", std::process::id()));
    std::fs::create_dir_all(&sockets).unwrap();
    let socket = sockets.join("app.sock");
    let ecatd = Ecatd::start(&[
        "--config",
        file.to_str().unwrap(),
        "--app-socket",
        socket.to_str().unwrap(),
    ]);
    std::fs::remove_file(&file).unwrap();
    let topology = Topology::default_segment();
    let shots = root().join("target/web-dashboard");
    std::fs::create_dir_all(&shots).unwrap();
    let foe = foe_content();
    let foe_file = std::env::temp_dir().join(format!("ecatd-web-{}.bin", std::process::id()));
    std::fs::write(&foe_file, &foe).unwrap();

    // The page itself: embedded, with a policy that allows nothing off-origin.
    let (status, page) = curl(&["-s", "-i", &format!("{}/", ecatd.http)]);
    assert_eq!(status, 200);
    assert!(
        page.contains("content-security-policy: default-src 'none'"),
        "{page}"
    );
    assert!(page.contains("<script type=\"module\" src=\"/static/app.js\">"));

    let args = serde_json::json!({
        "http": ecatd.http,
        "grpc": ecatd.grpc,
        "gateway": ecatd.gateway_addr().to_string(),
        "ecat": server_support::bin_dir().join("ecat"),
        "read_token": READ_TOKEN,
        "write_token": WRITE_TOKEN,
        "slave_count": topology.slaves.len(),
        "coe_write_value": COE_VALUE,
        // The drive's store holds 1 MiB in all: the new file replaces firmware.bin.
        "foe_name": "firmware.bin",
        "foe_file": foe_file,
        "bad_requests": BAD_REQUESTS,
        "emergency_code": EMERGENCY_CODE,
        "screenshots": shots,
    });
    let output = Command::new(venv_bin().join("python"))
        .arg(root().join("tests/py/web_dashboard.py"))
        .arg(args.to_string())
        .output()
        .expect("python runs");
    std::fs::remove_file(&foe_file).unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success(),
        "web_dashboard.py failed:\n{stderr}\n{stdout}"
    );
    let r: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
    assert_eq!(r["steps"], serde_json::json!([]), "every wait ended: {r:#}");

    // The token prompt, then the segment: every slave, named, in the state ecatd reports.
    assert_eq!(r["token_prompt"], true);
    assert!(r["role_label"].as_str().unwrap().starts_with("engineer"));
    let (_, slaves) = rest(&ecatd, READ_TOKEN, &[], "/api/v1/slaves");
    let slaves: serde_json::Value = serde_json::from_str(&slaves).unwrap();
    let shown = r["slaves"].as_array().unwrap();
    assert_eq!(shown.len(), topology.slaves.len());
    for (p, spec) in topology.slaves.iter().enumerate() {
        assert_eq!(shown[p]["position"], p);
        assert_eq!(shown[p]["name"], format!("{p}: {}", spec.name));
        assert_eq!(shown[p]["state"], slaves[p]["state"], "slave {p}");
    }

    // A state change from the CLI reached the open page without a reload.
    assert_eq!(r["cli_safeop"]["status"], 0, "{}", r["cli_safeop"]);
    assert_eq!(r["state_after_cli"], "SAFEOP");
    assert_eq!(r["not_reloaded"], true);
    assert_eq!(r["keyboard_view"], "#/events");

    // An emergency: in the log (filtered to emergencies only) and on the slave's page.
    assert_eq!(r["emergency_raised"], 200);
    let rows = r["events_filtered"].as_array().unwrap();
    assert_eq!(rows.len(), 1, "{rows:?}");
    let code = format!("0x{EMERGENCY_CODE:04x}");
    assert!(rows[0].as_str().unwrap().contains(&code), "{rows:?}");
    let shown = r["slave_emergencies"].as_str().unwrap();
    assert!(
        shown.contains(&format!("0x{EMERGENCY_CODE:04X}")),
        "{shown}"
    );

    // CoE: 0x1018:01 is the vendor id; the write, confirmed in a dialog that named slave,
    // object and value, reached the slave.
    assert_eq!(r["coe_1018_01"], SIM_VENDOR_ID.to_string());
    let asked = r["coe_confirm"].as_str().unwrap();
    for part in [
        format!("3: {}", topology.slaves[3].name),
        "0x2001:00".into(),
        COE_VALUE.to_string(),
    ] {
        assert!(asked.contains(&part), "{part:?} in {asked:?}");
    }
    let asked = r["foe_confirm"].as_str().unwrap();
    assert!(
        asked.contains("firmware.bin")
            && asked.contains(&format!("{} bytes", 1 << 20))
            && asked.contains(&sha256_hex(&foe)),
        "{asked}"
    );
    assert_eq!(r["coe_write_status"], "written");
    let (status, value) = rest(
        &ecatd,
        READ_TOKEN,
        &[],
        "/api/v1/slaves/3/coe/sdo/0x2001/0?type=u32",
    );
    assert_eq!(status, 200);
    let value: serde_json::Value = serde_json::from_str(&value).unwrap();
    assert_eq!(value["value"], COE_VALUE.to_string());

    // FoE: 1 MiB written with the bar at 100 %, and the same bytes read back.
    let digest = sha256_hex(&foe);
    assert_eq!(
        r["foe_write"]["progress"],
        100,
        "{}\n{}",
        r["foe_write"],
        ecatd.log()
    );
    assert_eq!(r["foe_write"]["sha256"], digest.as_str());
    assert_eq!(r["foe_read"]["progress"], 100, "{}", r["foe_read"]);
    assert_eq!(r["foe_read"]["sha256"], digest.as_str());
    assert_eq!(r["foe_read"]["size"], (1 << 20).to_string());
    let back = Command::new("curl")
        .args(["-sf", "-H", &format!("authorization: Bearer {READ_TOKEN}")])
        .arg(format!("{}/api/v1/slaves/0/foe/firmware.bin", ecatd.http))
        .output()
        .unwrap();
    assert_eq!(sha256_hex(&back.stdout), digest);

    // Gateway: no failures before, the failure rate above the 5 % line after.
    assert_eq!(r["gateway_before"], 0.0);
    assert!(
        r["gateway_after"].as_f64().unwrap() > 5.0,
        "{}",
        r["gateway_after"]
    );
    assert!(r["gateway_chart_last"].as_f64().unwrap() > 5.0);
    let (_, gateway) = rest(&ecatd, READ_TOKEN, &[], "/api/v1/gateway");
    let gateway: serde_json::Value = serde_json::from_str(&gateway).unwrap();
    let malformed = gateway["stats"]["failures"]["malformed"].as_u64().unwrap();
    assert_eq!(malformed, BAD_REQUESTS as u64);
    assert!(
        r["gateway_malformed"]
            .as_str()
            .unwrap()
            .contains(&format!("malformed\n{malformed}")),
        "{}",
        r["gateway_malformed"]
    );
    assert!(r["bus_period"].as_str().unwrap().ends_with("µs"));

    // Dark theme, and no sideways scrolling at a tablet's width.
    assert_eq!(r["dark_background"], "rgb(13, 17, 23)");
    assert_eq!(r["tablet_overflow"], false);

    // Read only: the badge, every write control drawn disabled and saying why, the value
    // shown, and ecatd refuses the write.
    assert!(r["read_role_label"].as_str().unwrap().starts_with("viewer"));
    assert_eq!(r["read_only_badge"], "read-only");
    for view in ["segment", "slave", "gateway"] {
        let controls = r[format!("read_only_{view}_controls")].as_array().unwrap();
        assert!(!controls.is_empty(), "{view} draws its write controls");
        for c in controls {
            assert_eq!(c["disabled"], true, "{view}: {c}");
            assert!(
                c["title"].as_str().unwrap().contains("write token"),
                "{view}: {c}"
            );
        }
    }
    assert_eq!(r["read_only_value"], COE_VALUE.to_string());
    let (status, _) = rest(
        &ecatd,
        READ_TOKEN,
        &[
            "-X",
            "PUT",
            "-H",
            "content-type: application/json",
            "-d",
            r#"{"value":"1","type":"auto"}"#,
        ],
        "/api/v1/slaves/3/coe/sdo/0x2001/0",
    );
    assert_eq!(status, 403);

    // The console: no error, except the refusals before the token was given, and requests
    // Chromium itself dropped because a network interface came or went on the host (the
    // tests beside this one make them; the page was opened again, `open_and_wait`).
    let console = r["console"].as_array().cloned().unwrap_or_default();
    let errors: Vec<_> = console
        .iter()
        .filter(|e| e["level"] == "SEVERE")
        .filter(|e| {
            let message = e["message"].as_str().unwrap_or("");
            let refused = e["phase"] == "token" && message.contains("status of 401");
            !(refused || message.contains("net::ERR_NETWORK_CHANGED"))
        })
        .collect();
    assert!(errors.is_empty(), "console errors: {errors:#?}");

    // Every request the page made went to ecatd on 127.0.0.1.
    let requests = r["requests"].as_array().unwrap();
    assert!(requests.len() > 20, "{requests:?}");
    let origin = format!("{}/", ecatd.http);
    let foreign: Vec<_> = requests
        .iter()
        .filter_map(|u| u.as_str())
        .filter(|u| !u.starts_with(&origin) && !u.starts_with("blob:") && !u.starts_with("data:"))
        .collect();
    assert!(foreign.is_empty(), "requests off 127.0.0.1: {foreign:?}");
    assert!(origin.starts_with("http://127.0.0.1:"));

    for shot in r["screenshots"].as_array().unwrap() {
        let len = std::fs::metadata(shot.as_str().unwrap()).unwrap().len();
        assert!(len > 10_000, "{shot} is {len} bytes");
    }
    drop(ecatd);
    let _ = std::fs::remove_dir_all(&sockets);
}

/// One browser at a time in this binary: two Chromium instances beside two ecatd on a
/// small machine make the live checks' deadlines a matter of luck.
fn one_browser() -> std::sync::MutexGuard<'static, ()> {
    static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());
    LOCK.lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// How long a page may take to show what the test waits for.
const PATIENCE: Duration = Duration::from_secs(60);
/// How long a value may take from the wire to the page: the page reads the stream every
/// 100 ms, so this is generous (a loaded machine), not the expected latency.
const LIVE: Duration = Duration::from_secs(10);
/// How long a page just opened is given before the test looks for requests Chromium dropped
/// on a network change (`Browser::open_and_wait`).
const FIRST_TRY: Duration = Duration::from_secs(20);

/// Whether a console entry is Chromium's own drop of a request on a host network change.
fn network_changed(entry: &serde_json::Value) -> bool {
    entry["message"]
        .as_str()
        .is_some_and(|m| m.contains("net::ERR_NETWORK_CHANGED"))
}

/// A headless Chromium driven over WebDriver (W3C, JSON over HTTP) by chromedriver, started
/// on a free port; the session ends and both stop on drop.
struct Browser {
    driver: Child,
    url: String,
    agent: ureq::Agent,
    /// Console entries and page requests read so far, tagged with the phase they came in.
    console: Vec<(String, serde_json::Value)>,
    requests: Vec<serde_json::Value>,
    phase: String,
}

/// The W3C WebDriver key for an element reference.
const ELEMENT: &str = "element-6066-11e4-a52e-4f735466cecf";

impl Browser {
    fn start() -> Browser {
        let mut driver = Command::new("chromedriver")
            .arg("--port=0")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("chromedriver runs (Debian package chromium-driver)");
        let stdout = driver.stdout.take().expect("stdout is piped");
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    return;
                }
            }
        });
        let port = loop {
            let line = rx
                .recv_timeout(PATIENCE)
                .expect("chromedriver reports its port");
            if let Some(rest) = line.split("started successfully on port ").nth(1) {
                break rest.trim_end_matches('.').trim().to_owned();
            }
        };
        let agent: ureq::Agent = ureq::Agent::config_builder()
            .http_status_as_error(false)
            .timeout_global(Some(PATIENCE))
            .build()
            .into();
        let mut browser = Browser {
            driver,
            url: format!("http://127.0.0.1:{port}"),
            agent,
            console: Vec::new(),
            requests: Vec::new(),
            phase: "start".into(),
        };
        let args = [
            "--headless=new",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",
            "--window-size=1280,800",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--disable-default-apps",
            "--disable-extensions",
            "--disable-domain-reliability",
            "--no-pings",
        ];
        let session = browser.call(
            "POST",
            "/session",
            serde_json::json!({"capabilities": {"alwaysMatch": {
                "browserName": "chrome",
                "goog:chromeOptions": {"binary": "/usr/bin/chromium", "args": args},
                "goog:loggingPrefs": {"browser": "ALL", "performance": "ALL"},
            }}}),
        );
        let id = session["sessionId"]
            .as_str()
            .unwrap_or_else(|| panic!("no session: {session}"));
        browser.url = format!("{}/session/{id}", browser.url);
        browser.viewport(1280, 800);
        browser
    }

    /// One WebDriver command: its `value`, panicking on a WebDriver error.
    fn call(&self, method: &str, path: &str, body: serde_json::Value) -> serde_json::Value {
        let answer = self.try_call(method, path, body);
        answer.unwrap_or_else(|err| panic!("WebDriver {method} {path}: {err}"))
    }

    fn try_call(
        &self,
        method: &str,
        path: &str,
        body: serde_json::Value,
    ) -> Result<serde_json::Value, String> {
        let url = format!("{}{path}", self.url);
        let response = match method {
            "GET" => self.agent.get(&url).call(),
            "DELETE" => self.agent.delete(&url).call(),
            _ => self
                .agent
                .post(&url)
                .header("content-type", "application/json")
                .send(body.to_string()),
        };
        let mut response = response.map_err(|e| e.to_string())?;
        let status = response.status().as_u16();
        let text = response
            .body_mut()
            .with_config()
            .limit(64 << 20)
            .read_to_string()
            .map_err(|e| e.to_string())?;
        let json: serde_json::Value = serde_json::from_str(&text).map_err(|e| e.to_string())?;
        if status == 200 {
            Ok(json["value"].clone())
        } else {
            Err(format!("{status}: {}", json["value"]))
        }
    }

    /// The page's own size (the window's includes the browser's frame).
    fn viewport(&self, width: u32, height: u32) {
        self.call(
            "POST",
            "/goog/cdp/execute",
            serde_json::json!({"cmd": "Emulation.setDeviceMetricsOverride", "params":
                {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": false}}),
        );
    }

    fn go(&self, url: &str) {
        self.call("POST", "/url", serde_json::json!({ "url": url }));
    }

    /// Runs `script` (a function body; `arguments` are `args`) and returns its result.
    fn js(&self, script: &str, args: serde_json::Value) -> serde_json::Value {
        self.call(
            "POST",
            "/execute/sync",
            serde_json::json!({"script": script, "args": args}),
        )
    }

    /// The element `css` selects, if the page has it.
    fn find(&self, css: &str) -> Option<String> {
        self.try_call(
            "POST",
            "/element",
            serde_json::json!({"using": "css selector", "value": css}),
        )
        .ok()
        .and_then(|v| v[ELEMENT].as_str().map(str::to_owned))
    }

    /// A click on `css` as a mouse would (WebDriver checks that it can be clicked).
    fn click(&self, css: &str) {
        let element = self
            .find(css)
            .unwrap_or_else(|| panic!("no {css} to click"));
        self.call(
            "POST",
            &format!("/element/{element}/click"),
            serde_json::json!({}),
        );
    }

    /// Keys typed into `css` (WebDriver focuses it first); `\u{E007}` is Enter.
    fn type_into(&self, css: &str, text: &str) {
        let element = self
            .find(css)
            .unwrap_or_else(|| panic!("no {css} to type into"));
        self.call(
            "POST",
            &format!("/element/{element}/value"),
            serde_json::json!({ "text": text }),
        );
    }

    /// Presses `keys` together on the focused element (`\u{E008}` Shift, `\u{E004}` Tab,
    /// `\u{E007}` Enter), then releases them.
    fn press(&self, keys: &[&str]) {
        let mut actions: Vec<serde_json::Value> = keys
            .iter()
            .map(|k| serde_json::json!({"type": "keyDown", "value": k}))
            .collect();
        actions.extend(
            keys.iter()
                .rev()
                .map(|k| serde_json::json!({"type": "keyUp", "value": k})),
        );
        self.call(
            "POST",
            "/actions",
            serde_json::json!({"actions": [{"type": "key", "id": "keyboard", "actions": actions}]}),
        );
    }

    /// Text of the first element `css` selects ("" when there is none).
    fn text(&self, css: &str) -> String {
        self.js(
            "const e = document.querySelector(arguments[0]); return e ? e.textContent : ''",
            serde_json::json!([css]),
        )
        .as_str()
        .unwrap_or_default()
        .to_owned()
    }

    /// Opens `url` and waits for `check`, as [`Browser::wait`]. Chromium drops the requests in
    /// flight when it sees a network interface come or go (`net::ERR_NETWORK_CHANGED`), and the
    /// tests beside this one make and remove namespaces, veth pairs and TAPs: a page whose
    /// script or reads were dropped so never gets there, and is loaded once more.
    fn open_and_wait<T>(
        &mut self,
        url: &str,
        what: &str,
        mut check: impl FnMut(&mut Browser) -> Option<T>,
    ) -> T {
        let dropped_before = self.network_changes();
        self.go(url);
        if let Some(value) = self.poll(FIRST_TRY, &mut check) {
            return value;
        }
        self.read_logs();
        if self.network_changes() > dropped_before {
            eprintln!("{what}: Chromium dropped requests on a network change; loading {url} again");
            self.call("POST", "/refresh", serde_json::json!({}));
        }
        self.wait(what, PATIENCE, check)
    }

    /// How many requests Chromium has dropped on a network change so far.
    fn network_changes(&self) -> usize {
        self.console
            .iter()
            .filter(|(_, e)| network_changed(e))
            .count()
    }

    /// Polls `check` until it gives a value or `patience` ends.
    fn poll<T>(
        &mut self,
        patience: Duration,
        check: &mut impl FnMut(&mut Browser) -> Option<T>,
    ) -> Option<T> {
        let deadline = Instant::now() + patience;
        loop {
            if let Some(value) = check(self) {
                return Some(value);
            }
            if Instant::now() > deadline {
                return None;
            }
            // Poll interval of the check; the loop ends on the condition or the deadline.
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Polls `check` until it gives a value; panics at `patience` with what the page showed.
    fn wait<T>(
        &mut self,
        what: &str,
        patience: Duration,
        mut check: impl FnMut(&mut Browser) -> Option<T>,
    ) -> T {
        if let Some(value) = self.poll(patience, &mut check) {
            return value;
        }
        self.read_logs();
        panic!(
            "timed out waiting for {what}; the page showed:\n{}\nconsole: {:#?}",
            self.text("#view"),
            self.console
        );
    }

    /// Moves the console and the page's requests seen so far into `console` and `requests`.
    fn read_logs(&mut self) {
        let browser = self.call("POST", "/se/log", serde_json::json!({"type": "browser"}));
        for entry in browser.as_array().into_iter().flatten() {
            self.console.push((self.phase.clone(), entry.clone()));
        }
        let performance = self.call(
            "POST",
            "/se/log",
            serde_json::json!({"type": "performance"}),
        );
        for entry in performance.as_array().into_iter().flatten() {
            if let Some(message) = entry["message"]
                .as_str()
                .and_then(|m| serde_json::from_str::<serde_json::Value>(m).ok())
            {
                self.requests.push(message["message"].clone());
            }
        }
    }

    /// Starts a new phase of the test (console entries are judged by phase).
    fn phase(&mut self, name: &str) {
        self.read_logs();
        name.clone_into(&mut self.phase);
    }

    /// A PNG of the whole page (the viewport grown to its height) at `path`.
    /// No console error after the start page but the one `allowed` names (its phase and a
    /// piece of its message), and every request the page made went to `ecatd`.
    fn assert_clean(&self, ecatd: &Ecatd, allowed: (&str, &str)) {
        let errors: Vec<_> = self
            .console
            .iter()
            .filter(|(phase, e)| phase != "start" && e["level"] == "SEVERE")
            .filter(|(_, e)| !network_changed(e))
            .filter(|(phase, e)| {
                !(phase == allowed.0
                    && e["message"].as_str().is_some_and(|m| m.contains(allowed.1)))
            })
            .collect();
        assert!(errors.is_empty(), "console errors: {errors:#?}");
        let origin = format!("{}/", ecatd.http);
        let foreign: Vec<_> = self
            .requests
            .iter()
            .filter(|m| m["method"] == "Network.requestWillBeSent")
            .filter_map(|m| m["params"]["request"]["url"].as_str())
            .filter(|u| !u.starts_with(&origin) && !u.starts_with("data:"))
            .collect();
        assert!(foreign.is_empty(), "requests off 127.0.0.1: {foreign:?}");
    }

    fn screenshot(&self, path: &std::path::Path) {
        let height = self
            .js(
                "window.scrollTo(0, 0); return document.documentElement.scrollHeight",
                serde_json::json!([]),
            )
            .as_u64()
            .unwrap_or(800) as u32;
        self.viewport(1280, height.max(800));
        let png = self.call("GET", "/screenshot", serde_json::Value::Null);
        self.viewport(1280, 800);
        std::fs::write(path, server_support::b64::decode(png.as_str().unwrap()))
            .expect("screenshot written");
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.try_call("DELETE", "", serde_json::Value::Null);
        let _ = self.driver.kill();
        let _ = self.driver.wait();
    }
}

/// The CiA 402 power state of a statusword: the standard's state coding (bits 0-3 and 6,
/// with bit 5 for the states where quick stop tells them apart).
fn cia402_state(statusword: u64) -> &'static str {
    match (statusword & 0x4F, statusword & 0x6F) {
        (0x00, _) => "Not ready to switch on",
        (0x40, _) => "Switch on disabled",
        (_, 0x21) => "Ready to switch on",
        (_, 0x23) => "Switched on",
        (_, 0x27) => "Operation enabled",
        (_, 0x07) => "Quick stop active",
        (0x0F, _) => "Fault reaction active",
        (0x08, _) => "Fault",
        _ => "Unknown state",
    }
}

/// GET `path` of ecatd's API with `token`, as JSON.
fn get_json(ecatd: &Ecatd, token: &str, path: &str) -> serde_json::Value {
    let (status, body) = rest(ecatd, token, &[], &format!("/api/v1{path}"));
    assert_eq!(status, 200, "GET {path}: {body}");
    serde_json::from_str(&body).unwrap()
}

/// Forces (`Some(value)`) or releases (`None`) an output over REST with the write token.
fn force_rest(
    ecatd: &Ecatd,
    slave: u16,
    index: u16,
    subindex: u8,
    value: Option<serde_json::Value>,
) {
    let path = format!("/api/v1/slaves/{slave}/process-data/0x{index:04X}/{subindex}");
    let (status, body) = match value {
        Some(value) => {
            let body = serde_json::json!({ "value": value }).to_string();
            rest(
                ecatd,
                WRITE_TOKEN,
                &[
                    "-X",
                    "PUT",
                    "-H",
                    "content-type: application/json",
                    "-d",
                    &body,
                ],
                &path,
            )
        }
        None => rest(ecatd, WRITE_TOKEN, &["-X", "DELETE"], &path),
    };
    assert_eq!(status, 200, "{path}: {body}");
}

/// The value of one entry in ecatd's last cycle.
fn value_of(ecatd: &Ecatd, slave: u16, index: u16, subindex: u8) -> serde_json::Value {
    let data = get_json(ecatd, READ_TOKEN, &format!("/slaves/{slave}/process-data"));
    data["entries"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["index"] == index && e["subindex"] == subindex)
        .unwrap_or_else(|| panic!("no 0x{index:04X}:{subindex} in {data}"))["value"]
        .clone()
}

/// The row id the page gives an entry.
fn row(slave: u16, index: u16, subindex: u8) -> String {
    format!("#pd-{slave}-{index:04x}-{subindex:02x}")
}

/// Whether the lamp of an entry is on in the page (None while it is not shown).
fn lamp_on(b: &Browser, slave: u16, index: u16, subindex: u8) -> Option<bool> {
    b.js(
        "const l = document.querySelector(arguments[0] + ' .lamp'); return l ? l.dataset.on : null",
        serde_json::json!([row(slave, index, subindex)]),
    )
    .as_str()
    .map(|on| on == "true")
}

/// The control program of the application tests (`tests/src/bin/app_program.rs`), owning
/// the outputs (`hold`: DO8 = 0x01 every cycle) until dropped.
struct Owner(Child);

impl Owner {
    fn claim(socket: &std::path::Path) -> Owner {
        let mut child = Command::new(env!("CARGO_BIN_EXE_app_program"))
            .arg(socket)
            .arg("hold")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("app_program starts");
        let stdout = child.stdout.take().expect("stdout is piped");
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                let _ = tx.send(line);
            }
        });
        let first = rx.recv_timeout(PATIENCE).expect("the program reports");
        assert!(first.contains("\"claimed\": true"), "{first}");
        Owner(child)
    }
}

impl Drop for Owner {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn the_process_data_page_shows_live_values_and_forces_outputs() {
    let _one = one_browser();
    let dir = std::env::temp_dir().join(format!("ecatd-web-pd-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let socket = dir.join("app.sock");
    let file = dir.join("ecatd.toml");
    // The tokens of the other test; the owner's watchdog at a second, so that a control
    // program slowed down by a busy machine keeps the outputs.
    let tokens = config();
    std::fs::write(
        &file,
        format!(
            "[app]\nwatchdog = 1000\n\n{}",
            std::fs::read_to_string(&tokens).unwrap()
        ),
    )
    .unwrap();
    std::fs::remove_file(&tokens).unwrap();
    let ecatd = Ecatd::start(&[
        "--config",
        file.to_str().unwrap(),
        "--app-socket",
        socket.to_str().unwrap(),
    ]);
    let shots = root().join("target/web-dashboard");
    std::fs::create_dir_all(&shots).unwrap();
    let slaves = get_json(&ecatd, READ_TOKEN, "/slaves");
    let name = |p: usize| format!("{p}: {}", slaves[p]["name"].as_str().unwrap());
    // The simulated segment: the drive at 0, the DO8 at 1 wired to the DI8 at 2.
    let (drive, do8, di8) = (0u16, 1u16, 2u16);
    assert_eq!(slaves[1]["name"], "ECATD-SIM DO8");
    assert_eq!(slaves[2]["name"], "ECATD-SIM DI8");

    let mut b = Browser::start();
    // The token in the tab's session storage before the dashboard loads (no 401 first):
    // a file of the same origin that runs no script of the dashboard.
    b.go(&format!("{}/static/favicon.svg", ecatd.http));
    b.js(
        "sessionStorage.setItem('ecatd.token', arguments[0])",
        serde_json::json!([WRITE_TOKEN]),
    );
    b.phase("page");
    b.open_and_wait(
        &format!("{}/#/process-data", ecatd.http),
        "the write role",
        |b| b.text("#role").contains("read and write").then_some(()),
    );
    assert_eq!(
        b.js(
            "return document.querySelector('nav a[data-view=\"process-data\"]').getAttribute('aria-current')",
            serde_json::json!([])
        ),
        "page"
    );

    // Every entry of ecatd's process image, with its name, object, type and direction.
    let expected = get_json(&ecatd, READ_TOKEN, "/process-data");
    let expected = expected["entries"].as_array().unwrap();
    let shown = b.wait("every entry", PATIENCE, |b| {
        let rows = b.js(
            "return [...document.querySelectorAll('tr.pd-entry')].map(tr => ({
                slave: Number(tr.dataset.slave), index: Number(tr.dataset.index),
                subindex: Number(tr.dataset.subindex), direction: tr.dataset.direction,
                name: tr.querySelector('.pd-name').textContent,
                cells: [...tr.cells].map(c => c.textContent)}))",
            serde_json::json!([]),
        );
        (rows.as_array().map_or(0, Vec::len) == expected.len()).then_some(rows)
    });
    for (e, s) in expected.iter().zip(shown.as_array().unwrap()) {
        for key in ["slave", "index", "subindex", "direction", "name"] {
            assert_eq!(e[key], s[key], "{key} of {e}");
        }
        let object = format!(
            "0x{:04X}:{:02X}",
            e["index"].as_u64().unwrap(),
            e["subindex"].as_u64().unwrap()
        );
        assert_eq!(s["cells"][1], object.as_str());
        assert_eq!(s["cells"][2], e["type"]);
    }
    let names: Vec<&str> = shown
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["name"].as_str().unwrap())
        .collect();
    for name in ["Controlword", "Statusword", "Output 1", "Input 1"] {
        assert!(names.contains(&name), "{name} in {names:?}");
    }
    b.wait("the value stream", PATIENCE, |b| {
        (b.text("#pd-live").starts_with("values: live")).then_some(())
    });
    let statusword = value_of(&ecatd, drive, 0x6041, 0).as_u64().unwrap();
    b.wait("the statusword decoded", PATIENCE, |b| {
        (b.text(&format!("{} .cia402-state", row(drive, 0x6041, 0))) == cia402_state(statusword))
            .then_some(())
    });

    // Live: DO8 output 1 forced over REST; the DI8's input 1 (wired to it) lights up.
    assert_eq!(value_of(&ecatd, di8, 0x6000, 1), false);
    assert_eq!(lamp_on(&b, di8, 0x6000, 1), Some(false));
    let forced_at = Instant::now();
    force_rest(&ecatd, do8, 0x7000, 1, Some(true.into()));
    b.wait("DI8 input 1 on", LIVE, |b| {
        lamp_on(b, di8, 0x6000, 1).filter(|on| *on)
    });
    let latency = forced_at.elapsed();
    b.wait("output 1 marked forced by engineer", LIVE, |b| {
        (b.text(&format!("{} .forced-by", row(do8, 0x7000, 1))) == "forced by engineer")
            .then_some(())
    });
    // Released, an output keeps its last value when no program owns the outputs.
    force_rest(&ecatd, do8, 0x7000, 1, Some(false.into()));
    b.wait("DI8 input 1 off again", LIVE, |b| {
        lamp_on(b, di8, 0x6000, 1).filter(|on| !on)
    });
    force_rest(&ecatd, do8, 0x7000, 1, None);
    b.wait("output 1 no longer marked", LIVE, |b| {
        b.text(&format!("{} .forced-by", row(do8, 0x7000, 1)))
            .is_empty()
            .then_some(())
    });
    eprintln!("force over REST to the lamp in the page: {latency:?}");

    // The trend of DI8 input 2, then output 2 forced in the page: a dialog names slave,
    // object and value, and nothing is written until it is confirmed (keyboard only).
    b.click(&format!("{} button.trend-pick", row(di8, 0x6000, 2)));
    b.wait("the trend of input 2", PATIENCE, |b| {
        b.text("#pd-trend figcaption")
            .contains("Input 2")
            .then_some(())
    });
    b.phase("force");
    let output2 = row(do8, 0x7000, 2);
    b.type_into(&format!("{output2} button.force"), "\u{E007}");
    b.wait("the force dialog", PATIENCE, |b| {
        b.js(
            "const d = document.getElementById('force-dialog'); return d && d.open",
            serde_json::json!([]),
        )
        .as_bool()
        .filter(|open| *open)
    });
    let dialog = b.text("#force-dialog");
    for part in [name(1).as_str(), "0x7000:02 Output 2", "on (1)"] {
        assert!(dialog.contains(part), "{part:?} in {dialog:?}");
    }
    let focused = |b: &Browser| b.js("return document.activeElement.id", serde_json::json!([]));
    assert_eq!(focused(&b), "force-cancel", "Cancel has the focus first");
    assert_eq!(
        get_json(&ecatd, READ_TOKEN, "/process-data/forced"),
        serde_json::json!([])
    );
    b.read_logs();
    let puts = |b: &Browser| {
        b.requests
            .iter()
            .filter(|m| m["method"] == "Network.requestWillBeSent")
            .filter(|m| m["params"]["request"]["method"] == "PUT")
            .count()
    };
    assert_eq!(
        puts(&b),
        0,
        "the page sent no write before the confirmation"
    );
    assert_eq!(value_of(&ecatd, do8, 0x7000, 2), false);
    b.press(&["\u{E008}", "\u{E004}"]);
    assert_eq!(focused(&b), "force-confirm");
    b.press(&["\u{E007}"]);
    let forced = b.wait("output 2 forced", PATIENCE, |_| {
        let forced = get_json(&ecatd, READ_TOKEN, "/process-data/forced");
        (forced.as_array().unwrap().len() == 1).then_some(forced)
    });
    assert_eq!(forced[0]["slave"], do8);
    assert_eq!(forced[0]["index"], 0x7000);
    assert_eq!(forced[0]["subindex"], 2);
    assert_eq!(forced[0]["value"], true);
    assert_eq!(forced[0]["forced_by"], "engineer");
    assert_eq!(forced[0]["override"], false);
    b.wait("the row marked forced", LIVE, |b| {
        (b.js(
            "const r = document.querySelector(arguments[0]); return r.classList.contains('forced') && r.dataset.forcedBy",
            serde_json::json!([output2]),
        ) == "engineer")
            .then_some(())
    });
    b.wait("DI8 input 2 on", LIVE, |b| {
        lamp_on(b, di8, 0x6000, 2).filter(|on| *on)
    });
    b.wait("the trend at 1", LIVE, |b| {
        (b.js(
            "return document.querySelector('#chart-trend path.line').dataset.last",
            serde_json::json!([]),
        ) == "1")
            .then_some(())
    });
    // A second sample at 1 on the chart, for the picture.
    b.wait("the trend's step", LIVE, |b| {
        let d = b.js(
            "return document.querySelector('#chart-trend path.line').getAttribute('d')",
            serde_json::json!([]),
        );
        (d.as_str().unwrap_or_default().matches('L').count() > 10).then_some(())
    });
    let shot = shots.join("process-data.png");
    b.screenshot(&shot);

    // Release from the page, behind a confirmation too: cancelled, the output stays forced.
    b.click(&format!("{output2} button.release"));
    b.wait("the release confirmation", PATIENCE, |b| {
        b.find("#confirm-cancel")
    });
    let asked = b.text("#confirm-dialog");
    for part in [name(1).as_str(), "0x7000:02 Output 2", "engineer"] {
        assert!(asked.contains(part), "{part:?} in {asked:?}");
    }
    b.click("#confirm-cancel");
    b.wait("the confirmation gone", PATIENCE, |b| {
        b.find("#confirm-dialog").is_none().then_some(())
    });
    assert_eq!(b.text(&format!("{output2} .force-status")), "not released");
    assert_eq!(
        get_json(&ecatd, READ_TOKEN, "/process-data/forced")
            .as_array()
            .unwrap()
            .len(),
        1
    );
    b.click(&format!("{output2} button.release"));
    b.wait("the release confirmation", PATIENCE, |b| {
        b.find("#confirm-ok")
    });
    b.click("#confirm-ok");
    b.wait("output 2 released", PATIENCE, |_| {
        (get_json(&ecatd, READ_TOKEN, "/process-data/forced") == serde_json::json!([]))
            .then_some(())
    });
    b.wait("the row no longer forced", LIVE, |b| {
        (b.text(&format!("{output2} .forced-by")).is_empty()).then_some(())
    });
    b.click(&format!("{output2} button.force"));
    b.wait("the dialog again", PATIENCE, |b| b.find("#force-cancel"));
    b.click("#force-cancel");
    b.wait("the dialog gone", PATIENCE, |b| {
        b.find("#force-dialog").is_none().then_some(())
    });
    assert_eq!(b.text(&format!("{output2} .force-status")), "not forced");
    assert_eq!(
        get_json(&ecatd, READ_TOKEN, "/process-data/forced"),
        serde_json::json!([])
    );
    b.read_logs();
    assert_eq!(puts(&b), 1, "one PUT: the confirmed force");

    // An application owns the outputs: ecatd refuses (409), the dialog says so and offers
    // the override as a second confirmation.
    let owner = Owner::claim(&socket);
    b.wait("the owner's DO8 output 1 on the DI8", LIVE, |b| {
        lamp_on(b, di8, 0x6000, 1).filter(|on| *on)
    });
    b.phase("override");
    let output3 = row(do8, 0x7000, 3);
    b.click(&format!("{output3} button.force"));
    b.wait("the force dialog", PATIENCE, |b| b.find("#force-confirm"));
    b.click("#force-confirm");
    let refusal = b.wait("the refusal", PATIENCE, |b| {
        b.find("#force-override").map(|_| b.text("#force-refusal"))
    });
    assert!(refusal.contains("owns the outputs"), "{refusal}");
    assert_eq!(b.text("#force-override"), "Force anyway (override)");
    assert_eq!(
        get_json(&ecatd, READ_TOKEN, "/process-data/forced"),
        serde_json::json!([])
    );
    b.click("#force-override");
    let forced = b.wait("output 3 forced over the owner", PATIENCE, |_| {
        let forced = get_json(&ecatd, READ_TOKEN, "/process-data/forced");
        (forced.as_array().unwrap().len() == 1).then_some(forced)
    });
    assert_eq!(forced[0]["subindex"], 3);
    assert_eq!(forced[0]["override"], true);
    assert_eq!(forced[0]["forced_by"], "engineer");
    b.wait("DI8 input 3 on", LIVE, |b| {
        lamp_on(b, di8, 0x6000, 3).filter(|on| *on)
    });
    b.wait("the dialog closed", PATIENCE, |b| {
        b.find("#force-dialog").is_none().then_some(())
    });
    b.click(&format!("{output3} button.release"));
    b.wait("the release confirmation", PATIENCE, |b| {
        b.find("#confirm-ok")
    });
    b.click("#confirm-ok");
    b.wait("output 3 released", PATIENCE, |_| {
        (get_json(&ecatd, READ_TOKEN, "/process-data/forced") == serde_json::json!([]))
            .then_some(())
    });
    drop(owner);
    b.phase("segment");

    // Leaving the page ends its value stream (the request is cancelled).
    b.open_and_wait(&format!("{}/#/bus", ecatd.http), "the bus view", |b| {
        b.find("#chart-cycle")
    });
    let streams_open = |b: &mut Browser| {
        b.read_logs();
        let started: Vec<String> = b
            .requests
            .iter()
            .filter(|m| m["method"] == "Network.requestWillBeSent")
            .filter(|m| {
                m["params"]["request"]["url"]
                    .as_str()
                    .is_some_and(|u| u.contains("/process-data/stream?interval=100ms"))
            })
            .filter_map(|m| m["params"]["requestId"].as_str().map(str::to_owned))
            .collect();
        let ended = |id: &String| {
            b.requests.iter().any(|m| {
                (m["method"] == "Network.loadingFailed" || m["method"] == "Network.loadingFinished")
                    && m["params"]["requestId"] == id.as_str()
            })
        };
        (
            started.len(),
            started.iter().filter(|id| !ended(id)).count(),
        )
    };
    let (started, _) = streams_open(&mut b);
    assert!(started >= 1, "the page read the stream with interval=100ms");
    b.wait("the page's value streams closed", PATIENCE, |b| {
        (streams_open(b).1 == 0).then_some(())
    });

    // The segment: the drive's CiA 402 state and the DI8's bits as lamps, live.
    let state = |b: &Browser| b.text("li.slave[data-position=\"0\"] .cia402-state");
    b.open_and_wait(
        &format!("{}/#/segment", ecatd.http),
        "the drive's state",
        |b| {
            (state(b) == cia402_state(value_of(&ecatd, drive, 0x6041, 0).as_u64().unwrap()))
                .then_some(())
        },
    );
    assert_eq!(state(&b), "Switch on disabled");
    // Shutdown (controlword 6): the drive goes to "Ready to switch on" on the wire.
    force_rest(&ecatd, drive, 0x6040, 0, Some(6.into()));
    b.wait("the drive's new state", LIVE, |b| {
        let statusword = value_of(&ecatd, drive, 0x6041, 0).as_u64().unwrap();
        (statusword & 0x6F == 0x21 && state(b) == cia402_state(statusword)).then_some(())
    });
    assert_eq!(state(&b), "Ready to switch on");
    // The owner gone, the safe outputs (all off) reach the DI8.
    let lamps = b.wait("the DI8's lamps, all off", PATIENCE, |b| {
        let lamps = b.js(
            "return [...document.querySelectorAll('li.slave[data-position=\"2\"] .lamp')].map(l => l.getAttribute('aria-label'))",
            serde_json::json!([]),
        );
        lamps.as_array()
            .is_some_and(|l| l.len() == 8 && l.iter().all(|a| a.as_str().is_some_and(|a| a.ends_with(": off"))))
            .then_some(lamps)
    });
    assert_eq!(lamps[0], "Input 1: off");
    force_rest(&ecatd, do8, 0x7000, 8, Some(true.into()));
    b.wait("DI8 input 8 on in the segment", LIVE, |b| {
        (b.js(
            "return document.querySelector('li.slave[data-position=\"2\"] .lamp[aria-label^=\"Input 8\"]').dataset.on",
            serde_json::json!([]),
        ) == "true")
            .then_some(())
    });

    // From a slave's page to its process data.
    b.open_and_wait(
        &format!("{}/#/slave/{do8}", ecatd.http),
        "the slave page's link",
        |b| b.find("#process-data-link"),
    );
    b.click("#process-data-link");
    b.wait("the DO8's process data alone", PATIENCE, |b| {
        let slaves = b.js(
            "return [...new Set([...document.querySelectorAll('tr.pd-entry')].map(tr => tr.dataset.slave))]",
            serde_json::json!([]),
        );
        (slaves == serde_json::json!(["1"])).then_some(())
    });
    b.phase("read-only");

    // Read only: forced outputs shown with who forced them, every force control disabled.
    b.js(
        "sessionStorage.setItem('ecatd.token', arguments[0]); location.hash = '#/process-data'; location.reload()",
        serde_json::json!([READ_TOKEN]),
    );
    b.wait("the read role", PATIENCE, |b| {
        b.text("#role").contains("read only").then_some(())
    });
    b.wait("every entry", PATIENCE, |b| {
        (b.js(
            "return document.querySelectorAll('tr.pd-entry').length",
            serde_json::json!([]),
        ) == expected.len())
        .then_some(())
    });
    b.wait("output 8 forced by engineer", LIVE, |b| {
        (b.text(&format!("{} .forced-by", row(do8, 0x7000, 8))) == "forced by engineer")
            .then_some(())
    });
    let controls = b.js(
        "return [...document.querySelectorAll('button.force, button.release, .force-value')].map(c => [c.disabled, c.title])",
        serde_json::json!([]),
    );
    let controls = controls.as_array().unwrap();
    assert!(!controls.is_empty());
    for c in controls {
        assert_eq!(c[0], true, "{c}");
        assert!(c[1].as_str().unwrap().contains("write token"), "{c}");
    }
    assert!(
        b.find(&format!(
            "{} button.release:not([hidden])",
            row(do8, 0x7000, 8)
        ))
        .is_some(),
        "the forced output's Release is shown (disabled)"
    );
    assert_eq!(b.text("#read-only-badge"), "read-only");
    force_rest(&ecatd, drive, 0x6040, 0, None);
    force_rest(&ecatd, do8, 0x7000, 8, None);
    b.phase("end");

    // The console: no error but the owner's refusal (409) the override phase provoked
    // ("start" is the icon page that put the token in place: Chrome asks it for
    // /favicon.ico, which ecatd does not have); every request went to ecatd.
    b.assert_clean(&ecatd, ("override", "status of 409"));
    let len = std::fs::metadata(&shot).unwrap().len();
    assert!(len > 10_000, "{} is {len} bytes", shot.display());
    drop(b);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The requests the page sent that are not reads (PUT, POST, DELETE), from Chrome's
/// performance log.
fn writes_sent(b: &mut Browser) -> Vec<String> {
    b.read_logs();
    b.requests
        .iter()
        .filter(|m| m["method"] == "Network.requestWillBeSent")
        .filter(|m| {
            !matches!(
                m["params"]["request"]["method"].as_str(),
                Some("GET" | "HEAD" | "OPTIONS")
            )
        })
        .map(|m| {
            format!(
                "{} {}",
                m["params"]["request"]["method"].as_str().unwrap_or(""),
                m["params"]["request"]["url"].as_str().unwrap_or("")
            )
        })
        .collect()
}

/// Waits for the write confirmation and returns its text.
fn confirmation(b: &mut Browser) -> String {
    b.wait("the confirmation", PATIENCE, |b| {
        b.js(
            "const d = document.getElementById('confirm-dialog'); return d && d.open",
            serde_json::json!([]),
        )
        .as_bool()
        .filter(|open| *open)
    });
    b.text("#confirm-dialog")
}

/// Presses `button` (`#confirm-ok` or `#confirm-cancel`) and waits for the dialog to go.
fn answer(b: &mut Browser, button: &str) {
    b.click(button);
    b.wait("the confirmation gone", PATIENCE, |b| {
        b.find("#confirm-dialog").is_none().then_some(())
    });
}

/// Every control inside the page's write controls: disabled?, title.
fn write_controls(b: &Browser) -> Vec<serde_json::Value> {
    b.js(
        "return [...document.querySelectorAll('.write')]
            .flatMap(el => el.matches('button, input, select') ? [el] : [...el.querySelectorAll('button, input, select')])
            .map(el => [el.disabled, el.title])",
        serde_json::json!([]),
    )
    .as_array()
    .cloned()
    .unwrap_or_default()
}

/// The rows of the events table: id, position, kind, time shown, the time element's stamp.
fn event_rows(b: &Browser) -> Vec<serde_json::Value> {
    b.js(
        "return [...document.querySelectorAll('#events tbody tr')].map(tr => [Number(tr.dataset.id),
            Number(tr.dataset.position), tr.dataset.kind, tr.cells[0].textContent,
            tr.querySelector('time').getAttribute('datetime')])",
        serde_json::json!([]),
    )
    .as_array()
    .cloned()
    .unwrap_or_default()
}

/// Issue 36's guardrails: no state is chosen before the user chooses one; every write asks
/// first, naming slave, object and value (Cancel sends nothing: ecatd's state, value and
/// event history unchanged; Confirm writes); a read token sees the write controls disabled
/// and a read-only badge; the events filters narrow the log to what ecatd's query answers.
#[test]
fn the_dashboard_asks_before_it_writes_and_filters_events() {
    let _one = one_browser();
    let file = config();
    let sockets = std::env::temp_dir().join(format!("ecatd-web-guard-{}", std::process::id()));
    std::fs::create_dir_all(&sockets).unwrap();
    let socket = sockets.join("app.sock");
    let ecatd = Ecatd::start(&[
        "--config",
        file.to_str().unwrap(),
        "--app-socket",
        socket.to_str().unwrap(),
    ]);
    std::fs::remove_file(&file).unwrap();
    let shots = root().join("target/web-dashboard");
    std::fs::create_dir_all(&shots).unwrap();
    let slaves = get_json(&ecatd, READ_TOKEN, "/slaves");
    let slaves = slaves.as_array().unwrap().clone();
    let count = slaves.len();
    let named = |p: usize| {
        format!(
            "{p}: {} (station 0x{:04X})",
            slaves[p]["name"].as_str().unwrap(),
            slaves[p]["station"].as_u64().unwrap()
        )
    };
    let state_of = |p: usize| get_json(&ecatd, READ_TOKEN, &format!("/slaves/{p}"));
    let state_changes_of_2 = || {
        get_json(&ecatd, READ_TOKEN, "/events?kind=state_changed&slave=2")
            .as_array()
            .unwrap()
            .len()
    };

    let mut b = Browser::start();
    b.go(&format!("{}/static/favicon.svg", ecatd.http));
    b.js(
        "sessionStorage.setItem('ecatd.token', arguments[0])",
        serde_json::json!([WRITE_TOKEN]),
    );
    b.phase("segment");
    b.open_and_wait(
        &format!("{}/#/segment", ecatd.http),
        "the write role",
        |b| b.text("#role").contains("read and write").then_some(()),
    );
    b.wait("every slave's state control", PATIENCE, |b| {
        (b.js(
            "return document.querySelectorAll('li.slave select.state-choice').length",
            serde_json::json!([]),
        ) == count)
            .then_some(())
    });

    // Nothing preselected: every state choice (all slaves and each one) shows the
    // placeholder, and every request button is disabled until a state is chosen.
    let choices = b.js(
        "return [...document.querySelectorAll('select.state-choice')].map(s => [s.value, s.selectedOptions[0].textContent, s.disabled])",
        serde_json::json!([]),
    );
    assert_eq!(choices.as_array().unwrap().len(), count + 1);
    for c in choices.as_array().unwrap() {
        assert_eq!(c, &serde_json::json!(["", "choose a state", false]));
    }
    let buttons = b.js(
        "return [...document.querySelectorAll('button.request-state')].map(x => x.disabled)",
        serde_json::json!([]),
    );
    assert_eq!(buttons, serde_json::json!(vec![true; count + 1]));
    // The write token: no badge, no control disabled for want of the role.
    assert_eq!(
        b.js(
            "return document.getElementById('read-only-badge').hidden",
            serde_json::json!([])
        ),
        true
    );
    let controls = write_controls(&b);
    assert!(controls.len() >= 2 * (count + 1), "{controls:?}");
    assert!(
        controls
            .iter()
            .all(|c| !c[1].as_str().unwrap().contains("write token")),
        "{controls:?}"
    );

    // One slave's state: the dialog names the slave, its state and the one asked for.
    assert_eq!(state_of(2)["state"], "OP");
    let changes = state_changes_of_2();
    let control = "li.slave[data-position=\"2\"] .state-control";
    b.click(&format!("{control} option[value=\"SAFEOP\"]"));
    b.wait("the request button enabled", PATIENCE, |b| {
        (b.js(
            "return document.getElementById('request-state-2').disabled",
            serde_json::json!([]),
        ) == false)
            .then_some(())
    });
    b.click("#request-state-2");
    let asked = confirmation(&mut b);
    for part in [
        named(2).as_str(),
        "NowOP",
        "Requested stateSAFEOP",
        "Request SAFEOP",
    ] {
        assert!(asked.contains(part), "{part:?} in {asked:?}");
    }
    assert_eq!(
        b.js("return document.activeElement.id", serde_json::json!([])),
        "confirm-cancel",
        "Cancel has the focus first"
    );
    b.screenshot(&shots.join("confirm-state.png"));
    answer(&mut b, "#confirm-cancel");
    assert_eq!(b.text(&format!("{control} [role=status]")), "not requested");
    let slave2 = state_of(2);
    assert_eq!(
        (&slave2["state"], &slave2["requested_state"]),
        (&"OP".into(), &"OP".into())
    );
    assert_eq!(state_changes_of_2(), changes, "no state change recorded");
    assert_eq!(writes_sent(&mut b), Vec::<String>::new());
    b.click("#request-state-2");
    confirmation(&mut b);
    answer(&mut b, "#confirm-ok");
    b.wait("slave 2 in SAFEOP", PATIENCE, |_| {
        (state_of(2)["state"] == "SAFEOP").then_some(())
    });
    b.wait("the request done", PATIENCE, |b| {
        (b.text(&format!("{control} [role=status]")) == "requested SAFEOP").then_some(())
    });
    // The choice goes back to the placeholder: the next request needs a new one.
    assert_eq!(
        b.js(
            "const s = document.querySelector(arguments[0] + ' select'); return [s.value, document.getElementById('request-state-2').disabled]",
            serde_json::json!([control])
        ),
        serde_json::json!(["", true])
    );
    assert_eq!(writes_sent(&mut b).len(), 1);

    // All slaves: the dialog says how many.
    b.click(".all-states option[value=\"OP\"]");
    b.wait("the all-slaves button enabled", PATIENCE, |b| {
        (b.js(
            "return document.getElementById('request-state-all').disabled",
            serde_json::json!([]),
        ) == false)
            .then_some(())
    });
    b.click("#request-state-all");
    let asked = confirmation(&mut b);
    let all = format!("Request OP for all {count} slaves");
    assert!(asked.contains(&all), "{all:?} in {asked:?}");
    assert!(asked.contains(&format!("all {count}: ")), "{asked}");
    for (p, slave) in slaves.iter().enumerate() {
        let name = slave["name"].as_str().unwrap();
        assert!(
            asked.contains(&format!("{p} {name}")),
            "{name} in {asked:?}"
        );
    }
    answer(&mut b, "#confirm-cancel");
    assert_eq!(state_of(2)["state"], "SAFEOP");
    assert_eq!(writes_sent(&mut b).len(), 1, "Cancel sent nothing");
    b.click("#request-state-all");
    confirmation(&mut b);
    answer(&mut b, "#confirm-ok");
    b.wait("every slave in OP", PATIENCE, |_| {
        let now = get_json(&ecatd, READ_TOKEN, "/slaves");
        now.as_array()
            .unwrap()
            .iter()
            .all(|s| s["state"] == "OP")
            .then_some(())
    });
    // Slave 2 was the one not in OP: the PUTs to the slaves after it may still be going.
    b.wait("the request for all done", PATIENCE, |b| {
        (b.text(".all-states [role=status]") == "requested OP").then_some(())
    });
    assert_eq!(writes_sent(&mut b).len(), 1 + count, "one PUT a slave");

    // An SDO write: named, cancelled (the value read back is unchanged), then confirmed.
    b.phase("slave");
    b.open_and_wait(
        &format!("{}/#/slave/3", ecatd.http),
        "the slave's state control",
        |b| b.find("#request-state-slave"),
    );
    assert_eq!(
        b.js(
            "return [document.querySelector('.view-head select.state-choice').value, document.getElementById('request-state-slave').disabled]",
            serde_json::json!([])
        ),
        serde_json::json!(["", true])
    );
    let sdo = |ecatd: &Ecatd| {
        get_json(ecatd, READ_TOKEN, "/slaves/3/coe/sdo/0x2001/0?type=u32")["value"].clone()
    };
    let before = sdo(&ecatd);
    assert_ne!(before, COE_VALUE.to_string());
    b.wait("0x2001's description", PATIENCE, |b| {
        let t = b.text("#object-2001 summary");
        (!t.is_empty() && !t.contains('…')).then_some(())
    });
    b.click("#object-2001 summary");
    b.wait("0x2001:00's editor", PATIENCE, |b| {
        b.find("#entry-2001-00 .editor")
    });
    b.type_into("#entry-2001-00 .editor", &COE_VALUE.to_string());
    b.click("#entry-2001-00 button.write-value");
    let asked = confirmation(&mut b);
    for part in [
        named(3),
        "0x2001:00".into(),
        format!("New value{COE_VALUE}"),
        "Write value".into(),
    ] {
        assert!(asked.contains(&part), "{part:?} in {asked:?}");
    }
    answer(&mut b, "#confirm-cancel");
    assert_eq!(b.text("#entry-2001-00 .write-status"), "not written");
    assert_eq!(sdo(&ecatd), before, "Cancel wrote nothing");
    assert_eq!(writes_sent(&mut b).len(), 1 + count);
    b.click("#entry-2001-00 button.write-value");
    confirmation(&mut b);
    answer(&mut b, "#confirm-ok");
    b.wait("the write done", PATIENCE, |b| {
        (b.text("#entry-2001-00 .write-status") == "written").then_some(())
    });
    assert_eq!(sdo(&ecatd), COE_VALUE.to_string());

    // A read token: the badge, and every write control drawn but disabled, saying why.
    b.phase("read-only");
    b.js(
        "sessionStorage.setItem('ecatd.token', arguments[0]); location.hash = '#/segment'; location.reload()",
        serde_json::json!([READ_TOKEN]),
    );
    b.wait("the read role", PATIENCE, |b| {
        b.text("#role").contains("read only").then_some(())
    });
    b.wait("every slave's state control", PATIENCE, |b| {
        (b.js(
            "return document.querySelectorAll('li.slave select.state-choice').length",
            serde_json::json!([]),
        ) == count)
            .then_some(())
    });
    assert_eq!(
        b.js(
            "const e = document.getElementById('read-only-badge'); return !e.hidden && getComputedStyle(e).display !== 'none' && e.textContent",
            serde_json::json!([])
        ),
        "read-only"
    );
    let read_only = |b: &Browser, view: &str| {
        let controls = write_controls(b);
        assert!(!controls.is_empty(), "{view} draws its write controls");
        for c in &controls {
            assert_eq!(c[0], true, "{view}: {c}");
            assert!(
                c[1].as_str().unwrap().contains("write token"),
                "{view}: {c}"
            );
        }
        controls.len()
    };
    assert_eq!(read_only(&b, "segment"), 2 * (count + 1));
    b.screenshot(&shots.join("segment-read-only.png"));
    b.open_and_wait(
        &format!("{}/#/slave/3", ecatd.http),
        "the slave's state control",
        |b| b.find("#request-state-slave"),
    );
    b.wait("0x2001's description", PATIENCE, |b| {
        let t = b.text("#object-2001 summary");
        (!t.is_empty() && !t.contains('…')).then_some(())
    });
    b.click("#object-2001 summary");
    b.wait("0x2001:00's editor", PATIENCE, |b| {
        b.find("#entry-2001-00 .editor")
    });
    read_only(&b, "slave");
    assert_eq!(
        writes_sent(&mut b).len(),
        1 + count + 1,
        "nothing written with the read token"
    );

    // Events: the history with filters, each event's time in UTC.
    b.phase("events");
    b.open_and_wait(&format!("{}/#/events", ecatd.http), "the log", |b| {
        (event_rows(b).len() > 5).then_some(())
    });
    let unfiltered = event_rows(&b).len();
    let history = get_json(&ecatd, READ_TOKEN, "/events?limit=1000");
    let newest = history.as_array().unwrap().last().unwrap().clone();
    let rows = event_rows(&b);
    let (time, stamp) = (rows[0][3].as_str().unwrap(), &rows[0][4]);
    assert_eq!(stamp, &newest["time"]);
    // 2026-11-29T07:10:00.123Z is shown as 2026-11-29 07:10:00.123 UTC.
    let utc = newest["time"]
        .as_str()
        .unwrap()
        .replace('T', " ")
        .replace('Z', " UTC");
    assert_eq!(time, utc);

    let filtered = |b: &mut Browser, what: &str| {
        b.wait(what, PATIENCE, |b| {
            (b.js(
                "return document.querySelector('#events tbody').dataset.filtered",
                serde_json::json!([]),
            ) == "server")
                .then_some(())
        });
        event_rows(b)
    };
    let ids = |rows: &[serde_json::Value]| -> Vec<u64> {
        rows.iter().map(|r| r[0].as_u64().unwrap()).collect()
    };
    let expected_ids = |query: &str| -> Vec<u64> {
        let mut ids: Vec<u64> = get_json(&ecatd, READ_TOKEN, &format!("/events?{query}"))
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e["id"].as_u64().unwrap())
            .collect();
        ids.reverse();
        ids
    };
    b.type_into("#event-slave", "2\u{E007}");
    let of_2 = filtered(&mut b, "the log of slave 2");
    assert!(!of_2.is_empty() && of_2.len() < unfiltered, "{of_2:?}");
    assert!(of_2.iter().all(|r| r[1] == 2), "{of_2:?}");
    assert_eq!(ids(&of_2), expected_ids("slave=2&limit=1000"));
    // By the slave's name: the same events.
    let name = slaves[2]["name"].as_str().unwrap();
    let short = name.rsplit(' ').next().unwrap();
    assert_eq!(
        slaves
            .iter()
            .filter(|s| s["name"].as_str().unwrap().contains(short))
            .count(),
        1
    );
    b.js(
        "const e = document.getElementById('event-slave'); e.value = ''; document.querySelector('#events tbody').dataset.filtered = ''",
        serde_json::json!([]),
    );
    b.type_into("#event-slave", &format!("{short}\u{E007}"));
    assert_eq!(
        ids(&filtered(&mut b, "the log of the DI8 by name")),
        ids(&of_2)
    );
    // And by kind: its state changes (SAFEOP, then OP again, above).
    b.click("#event-kind option[value=\"state_changed\"]");
    let changes = b.wait("the state changes of slave 2", PATIENCE, |b| {
        let rows = event_rows(b);
        (!rows.is_empty() && rows.iter().all(|r| r[2] == "state_changed")).then_some(rows)
    });
    assert_eq!(
        ids(&changes),
        expected_ids("slave=2&kind=state_changed&limit=1000")
    );
    assert!(changes.len() >= 2, "{changes:?}");
    b.screenshot(&shots.join("events-filtered.png"));
    // Since: a time (the last change) and a span back.
    let last = get_json(&ecatd, READ_TOKEN, "/events?slave=2&kind=state_changed")
        .as_array()
        .unwrap()
        .last()
        .unwrap()["time"]
        .as_str()
        .unwrap()
        .to_owned();
    b.js(
        "document.querySelector('#events tbody').dataset.filtered = ''",
        serde_json::json!([]),
    );
    b.type_into("#event-since", &format!("{last}\u{E007}"));
    let since = filtered(&mut b, "the changes since the last one");
    assert_eq!(
        ids(&since),
        expected_ids(&format!(
            "slave=2&kind=state_changed&since={last}&limit=1000"
        ))
    );
    assert!(
        !since.is_empty() && since.len() < changes.len(),
        "{since:?}"
    );
    // A span ecatd cannot read: said, and no event shown as if it matched.
    b.phase("events-bad");
    b.js(
        "const e = document.getElementById('event-since'); e.value = ''; document.querySelector('#events tbody').dataset.filtered = ''",
        serde_json::json!([]),
    );
    b.type_into("#event-since", "yesterday\u{E007}");
    assert!(filtered(&mut b, "the refusal").is_empty());
    let said = b.text("#event-error");
    assert!(said.contains("since"), "{said}");
    b.phase("end");

    // No console error but the refused filter (400), no request off 127.0.0.1.
    b.assert_clean(&ecatd, ("events-bad", "status of 400"));
    drop(b);
    drop(ecatd);
    let _ = std::fs::remove_dir_all(&sockets);
}
