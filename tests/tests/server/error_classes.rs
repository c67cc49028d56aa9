//! The error-mapping table of `docs/call-it.md` ("Errors") through both APIs: each class of
//! fault gives its gRPC code and HTTP status, the `google.rpc.ErrorInfo` reason in
//! UPPER_SNAKE_CASE, the protocol's code in its own field, and for an invalid argument the
//! field at fault (`google.rpc.BadRequest`, and `field` in the problem+json body).

use crate::server_support;

use serde_json::Value;
use server_support::{Ecatd, b64, call_status, curl};

/// One fault: how to cause it over gRPC and REST, and what both must answer.
struct Fault {
    what: &'static str,
    grpc: (&'static str, String),
    rest: (&'static str, &'static str, &'static str),
    code: u64,
    http: u16,
    reason: &'static str,
    protocol_code: Option<u64>,
    field: Option<&'static str>,
}

fn rest(ecatd: &Ecatd, method: &str, path: &str, body: &str) -> (u16, String, Value) {
    let url = format!("{}{path}", ecatd.http);
    let mut args = vec!["-s", "-i", "-X", method, &url];
    if !body.is_empty() {
        args.extend(["-H", "content-type: application/json", "-d", body]);
    }
    let (status, text) = curl(&args);
    let (head, body) = text.split_once("\r\n\r\n").unwrap_or((&text, ""));
    (
        status,
        head.to_ascii_lowercase(),
        serde_json::from_str(body).unwrap_or(Value::String(body.to_owned())),
    )
}

#[test]
fn each_class_of_fault_has_its_code_through_grpc_and_rest() {
    let ecatd = Ecatd::start(&[]);
    let faults = [
        Fault {
            what: "an object the slave does not have",
            grpc: (
                "ecat.v1.CoeService/Upload",
                r#"{"slave":"pos:0","index":24576,"subindex":1}"#.into(),
            ),
            rest: ("GET", "/api/v1/slaves/pos:0/coe/sdo/0x6000/1", ""),
            code: 5,
            http: 404,
            reason: "SDO_ABORT",
            protocol_code: Some(0x0602_0000),
            field: None,
        },
        Fault {
            what: "a slave that is not there",
            grpc: (
                "ecat.v1.BusService/GetSlave",
                r#"{"slave":"station:4242"}"#.into(),
            ),
            rest: ("GET", "/api/v1/slaves/station:4242", ""),
            code: 5,
            http: 404,
            reason: "UNKNOWN_SLAVE",
            protocol_code: None,
            field: None,
        },
        Fault {
            what: "a malformed slave name",
            grpc: (
                "ecat.v1.BusService/GetSlave",
                r#"{"slave":"slot:3"}"#.into(),
            ),
            rest: ("GET", "/api/v1/slaves/slot:3", ""),
            code: 3,
            http: 400,
            reason: "INVALID_ARGUMENT",
            protocol_code: None,
            field: Some("slave"),
        },
        Fault {
            what: "a value of the wrong size",
            grpc: (
                "ecat.v1.CoeService/Download",
                format!(
                    r#"{{"slave":"station:1004","index":8193,"subindex":0,"data":"{}"}}"#,
                    b64::encode(&[1, 2])
                ),
            ),
            rest: (
                "PUT",
                "/api/v1/slaves/station:1004/coe/sdo/0x2001/0",
                r#"{"data":"0102"}"#,
            ),
            code: 3,
            http: 400,
            reason: "SDO_ABORT",
            protocol_code: Some(0x0607_0013),
            field: None,
        },
        Fault {
            what: "a read-only IDN",
            grpc: (
                "ecat.v1.SoeService/Write",
                format!(
                    r#"{{"slave":"pos:0","idn":32868,"data":"{}"}}"#,
                    b64::encode(&[1, 0])
                ),
            ),
            rest: (
                "PUT",
                "/api/v1/slaves/pos:0/soe/0/P-0-0100",
                r#"{"data":"0100"}"#,
            ),
            code: 9,
            http: 409,
            reason: "SOE_ERROR",
            protocol_code: Some(0x7004),
            field: None,
        },
        Fault {
            what: "a protocol the slave does not speak",
            grpc: (
                "ecat.v1.SoeService/Read",
                r#"{"slave":"pos:3","idn":32868}"#.into(),
            ),
            rest: ("GET", "/api/v1/slaves/pos:3/soe/0/P-0-0100", ""),
            code: 9,
            http: 409,
            reason: "UNSUPPORTED",
            protocol_code: None,
            field: None,
        },
    ];
    for f in &faults {
        let status = call_status(&ecatd.grpc, &[], f.grpc.0, &f.grpc.1).expect_err(f.what);
        assert_eq!(
            status["code"].as_u64(),
            Some(f.code),
            "{}: {status}",
            f.what
        );
        let details = status["details"].as_array().cloned().unwrap_or_default();
        let info = details
            .iter()
            .find(|d| d["@type"] == "type.googleapis.com/google.rpc.ErrorInfo")
            .unwrap_or_else(|| panic!("{}: no ErrorInfo in {status}", f.what));
        assert_eq!(info["reason"], f.reason, "{}", f.what);
        assert_eq!(info["domain"], "ecat.v1");
        if let Some(code) = f.protocol_code {
            // At the protocol's width: 32-bit abort codes as IgH's 0x%08X, 16-bit codes 0x%04X.
            let width = if matches!(f.reason, "SDO_ABORT" | "FOE_ERROR") {
                8
            } else {
                4
            };
            assert_eq!(
                info["metadata"]["code"],
                format!("0x{code:0width$X}"),
                "{}",
                f.what
            );
        }
        let violation = details
            .iter()
            .find(|d| d["@type"] == "type.googleapis.com/google.rpc.BadRequest")
            .map(|d| d["fieldViolations"][0]["field"].clone());
        assert_eq!(
            violation.as_ref().and_then(Value::as_str),
            f.field,
            "{}: {status}",
            f.what
        );

        let (http, head, body) = rest(&ecatd, f.rest.0, f.rest.1, f.rest.2);
        assert_eq!(http, f.http, "{}: {body}", f.what);
        assert!(
            head.contains("content-type: application/problem+json"),
            "{}: RFC 9457 media type:\n{head}",
            f.what
        );
        assert_eq!(body["status"], f.http, "{}", f.what);
        assert_eq!(body["reason"], f.reason, "{}", f.what);
        assert_eq!(body["grpc_code"].as_u64(), Some(f.code), "{}", f.what);
        assert!(
            body["type"]
                .as_str()
                .is_some_and(|t| t.starts_with("urn:ecat:error:"))
        );
        assert!(body["detail"].as_str().is_some_and(|d| !d.is_empty()));
        assert_eq!(
            body["protocol_code"].as_u64(),
            f.protocol_code,
            "{}: {body}",
            f.what
        );
        assert_eq!(body["field"].as_str(), f.field, "{}: {body}", f.what);
    }
}

#[test]
fn grpc_health_follows_readiness() {
    let ecatd = Ecatd::start(&[]);
    // Ecatd::start returns once /readyz answers 200: the health service must agree.
    let health = call_status(&ecatd.grpc, &[], "grpc.health.v1.Health/Check", "{}").unwrap();
    assert_eq!(health["status"], "SERVING");
    let bus = call_status(
        &ecatd.grpc,
        &[],
        "grpc.health.v1.Health/Check",
        r#"{"service":"ecat.v1.BusService"}"#,
    )
    .unwrap();
    assert_eq!(bus["status"], "SERVING");
}
