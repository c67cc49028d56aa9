//! Who may call what: the one table of every REST route and gRPC method with the role it
//! needs. `http::auth` and `grpc::auth` decide from it, and the role-table test walks every
//! route of the served OpenAPI document and every method gRPC reflection lists against it,
//! so a new route or method that is not declared here fails that test (and is refused to
//! read tokens meanwhile: an undeclared call needs the write role).
//!
//! Finer rules that depend on a request's arguments (a register read over a mailbox
//! SyncManager area) live in the service layer ([`crate::service::Core::read_register`]).

use crate::security::Role;

/// What a call needs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    /// No token (probes, scrapers, the API's own description).
    Public,
    /// A read or write token.
    Read,
    /// A write token.
    Write,
}

impl Access {
    /// The role a caller needs, `None` for public calls.
    pub fn role(self) -> Option<Role> {
        match self {
            Access::Public => None,
            Access::Read => Some(Role::Read),
            Access::Write => Some(Role::Write),
        }
    }

    /// The table's spelling: `public`, `read` or `write`.
    pub fn name(self) -> &'static str {
        match self {
            Access::Public => "public",
            Access::Read => "read",
            Access::Write => "write",
        }
    }
}

use Access::{Public, Read, Write};

/// Every HTTP route: method, path (as the router declares it, `{name}` for a parameter),
/// access. The `/api/v1` routes are the OpenAPI document's paths with that prefix.
pub const REST: &[(&str, &str, Access)] = &[
    ("GET", "/healthz", Public),
    ("GET", "/readyz", Public),
    ("GET", "/metrics", Public),
    // The dashboard's files (`http::web`); its data comes through `/api/v1`.
    ("GET", "/", Public),
    ("GET", "/static/{*file}", Public),
    ("GET", "/api/v1/openapi.json", Public),
    ("GET", "/api/v1/slaves", Read),
    ("GET", "/api/v1/slaves/{slave}", Read),
    ("PUT", "/api/v1/slaves/{slave}/state", Write),
    ("POST", "/api/v1/rescan", Write),
    ("GET", "/api/v1/events", Read),
    ("GET", "/api/v1/bus", Read),
    ("GET", "/api/v1/process-data/layout", Read),
    ("GET", "/api/v1/process-data", Read),
    ("GET", "/api/v1/process-data/forced", Read),
    ("GET", "/api/v1/process-data/stream", Read),
    ("GET", "/api/v1/slaves/{slave}/process-data", Read),
    (
        "PUT",
        "/api/v1/slaves/{slave}/process-data/{index}/{subindex}",
        Write,
    ),
    (
        "DELETE",
        "/api/v1/slaves/{slave}/process-data/{index}/{subindex}",
        Write,
    ),
    ("GET", "/api/v1/session", Read),
    // Read, but a read over a mailbox SyncManager area needs a write token (service layer).
    ("GET", "/api/v1/slaves/{slave}/registers/{address}", Read),
    ("PUT", "/api/v1/slaves/{slave}/registers/{address}", Write),
    ("GET", "/api/v1/slaves/{slave}/sii", Read),
    ("PUT", "/api/v1/slaves/{slave}/sii/{word}", Write),
    ("PUT", "/api/v1/slaves/{slave}/alias", Write),
    (
        "GET",
        "/api/v1/slaves/{slave}/coe/sdo/{index}/{subindex}",
        Read,
    ),
    (
        "PUT",
        "/api/v1/slaves/{slave}/coe/sdo/{index}/{subindex}",
        Write,
    ),
    ("GET", "/api/v1/slaves/{slave}/coe/od", Read),
    ("GET", "/api/v1/slaves/{slave}/coe/od/{index}", Read),
    (
        "GET",
        "/api/v1/slaves/{slave}/coe/od/{index}/{subindex}",
        Read,
    ),
    ("GET", "/api/v1/slaves/{slave}/soe/{drive}/{idn}", Read),
    ("PUT", "/api/v1/slaves/{slave}/soe/{drive}/{idn}", Write),
    ("GET", "/api/v1/slaves/{slave}/foe/{name}", Read),
    ("PUT", "/api/v1/slaves/{slave}/foe/{name}", Write),
    // A VoE message may do anything the vendor defined.
    ("POST", "/api/v1/slaves/{slave}/voe", Write),
    ("GET", "/api/v1/slaves/{slave}/eoe/ip", Read),
    ("PUT", "/api/v1/slaves/{slave}/eoe/ip", Write),
    ("GET", "/api/v1/master", Read),
    ("GET", "/api/v1/capture", Write),
    (
        "POST",
        "/api/v1/slaves/{slave}/registers/{address}/rdwr",
        Write,
    ),
    ("GET", "/api/v1/domains", Read),
    ("GET", "/api/v1/log-filter", Read),
    ("PUT", "/api/v1/log-filter", Write),
    ("GET", "/api/v1/eoe/interfaces", Read),
    ("GET", "/api/v1/gateway", Read),
    ("GET", "/api/v1/config", Read),
    ("POST", "/api/v1/gateway/start", Write),
    ("POST", "/api/v1/gateway/stop", Write),
    // `--simulate` only, not in the OpenAPI document.
    ("POST", "/api/v1/slaves/{slave}/sim/emergency", Write),
];

/// Every gRPC method: `/package.Service/Method` (the HTTP/2 path), access.
pub const GRPC: &[(&str, Access)] = &[
    ("/grpc.health.v1.Health/Check", Public),
    ("/grpc.health.v1.Health/Watch", Public),
    ("/grpc.health.v1.Health/List", Public),
    (
        "/grpc.reflection.v1.ServerReflection/ServerReflectionInfo",
        Public,
    ),
    (
        "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo",
        Public,
    ),
    ("/ecat.v1.BusService/ListSlaves", Read),
    ("/ecat.v1.BusService/GetSlave", Read),
    ("/ecat.v1.BusService/RequestState", Write),
    ("/ecat.v1.BusService/Rescan", Write),
    ("/ecat.v1.BusService/WatchEvents", Read),
    // Read, but a read over a mailbox SyncManager area needs a write token (service layer).
    ("/ecat.v1.BusService/ReadRegister", Read),
    ("/ecat.v1.BusService/WriteRegister", Write),
    ("/ecat.v1.BusService/ReadSii", Read),
    ("/ecat.v1.BusService/WriteSii", Write),
    ("/ecat.v1.BusService/SetAlias", Write),
    ("/ecat.v1.BusService/GetConfig", Read),
    ("/ecat.v1.BusService/GetMaster", Read),
    // The frames carry every mailbox transfer, FoE passwords included.
    ("/ecat.v1.BusService/Capture", Write),
    ("/ecat.v1.BusService/ReadWriteRegister", Write),
    ("/ecat.v1.BusService/ListDomains", Read),
    ("/ecat.v1.BusService/GetLogFilter", Read),
    // Changing what ecatd logs is the operator's (ecatd has no role above write).
    ("/ecat.v1.BusService/SetLogFilter", Write),
    ("/ecat.v1.CoeService/Upload", Read),
    ("/ecat.v1.CoeService/Download", Write),
    ("/ecat.v1.CoeService/ObjectList", Read),
    ("/ecat.v1.CoeService/ObjectDescription", Read),
    ("/ecat.v1.CoeService/EntryDescription", Read),
    ("/ecat.v1.SoeService/Read", Read),
    ("/ecat.v1.SoeService/Write", Write),
    ("/ecat.v1.FoeService/Read", Read),
    ("/ecat.v1.FoeService/Write", Write),
    ("/ecat.v1.FoeService/WriteWithProgress", Write),
    ("/ecat.v1.VoeService/Transfer", Write),
    ("/ecat.v1.EoeService/SetIp", Write),
    ("/ecat.v1.EoeService/GetIp", Read),
    ("/ecat.v1.EoeService/ListInterfaces", Read),
    ("/ecat.v1.GatewayService/GetGateway", Read),
    ("/ecat.v1.GatewayService/StartGateway", Write),
    ("/ecat.v1.GatewayService/StopGateway", Write),
    ("/ecat.v1.ProcessDataService/GetLayout", Read),
    ("/ecat.v1.ProcessDataService/Read", Read),
    ("/ecat.v1.ProcessDataService/Watch", Read),
    ("/ecat.v1.ProcessDataService/ListForced", Read),
    // Forcing writes outputs over whatever the control program commits (audited).
    ("/ecat.v1.ProcessDataService/Force", Write),
    ("/ecat.v1.ProcessDataService/ReleaseForce", Write),
];

/// The access of HTTP `method` on the route `path` (as declared, e.g. from axum's
/// `MatchedPath`); HEAD is GET's. `None`: not in the table.
pub fn rest(method: &str, path: &str) -> Option<Access> {
    let method = if method == "HEAD" { "GET" } else { method };
    REST.iter()
        .find(|(m, p, _)| *m == method && *p == path)
        .map(|(_, _, access)| *access)
}

/// The access of the gRPC method at `path` (`/package.Service/Method`). `None`: not in the
/// table.
pub fn grpc(path: &str) -> Option<Access> {
    GRPC.iter()
        .find(|(p, _)| *p == path)
        .map(|(_, access)| *access)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entries_are_unique_and_found() {
        for (i, (m, p, a)) in REST.iter().enumerate() {
            assert!(
                !REST[..i].iter().any(|(m2, p2, _)| m2 == m && p2 == p),
                "{m} {p} twice"
            );
            assert_eq!(rest(m, p), Some(*a));
        }
        for (i, (p, a)) in GRPC.iter().enumerate() {
            assert!(!GRPC[..i].iter().any(|(p2, _)| p2 == p), "{p} twice");
            assert_eq!(grpc(p), Some(*a));
        }
        assert_eq!(rest("HEAD", "/api/v1/slaves"), Some(Read));
        assert_eq!(rest("DELETE", "/api/v1/slaves"), None);
        assert_eq!(grpc("/ecat.v1.BusService/Nope"), None);
    }
}
