//! Browser safety (CSRF and DNS rebinding): a web page open in the operator's browser must
//! not be able to drive the API on a loopback listener.
//!
//! - Every request needs a `Host` that names this server: a loopback name or address, the
//!   listener's own address, or a configured name. A rebound DNS name (`evil.example`
//!   resolving to 127.0.0.1) carries its own name and is refused.
//! - A request that is not GET/HEAD/OPTIONS must carry a JSON (or `application/octet-stream`)
//!   content type or the `X-Ecat-Client` / `X-Requested-With` header: a cross-origin page
//!   can send neither without a CORS preflight, which ecatd never grants.
//! - An `Origin`, when present, must name the same host as `Host`.

use std::net::{IpAddr, SocketAddr};
use std::sync::Arc;

use axum::extract::{Request, State};
use axum::http::{Method, StatusCode, header};
use axum::middleware::Next;
use axum::response::Response;

use super::error::problem;
use crate::service::ApiError;

/// The custom header a non-browser client may send instead of a JSON content type.
pub const CLIENT_HEADER: &str = "x-ecat-client";

/// The host names the HTTP API answers to.
#[derive(Debug, Clone)]
pub struct AllowedHosts(Arc<Vec<String>>);

impl AllowedHosts {
    /// Loopback names, the listener's address `listen`, and `extra` (names or addresses,
    /// without port).
    pub fn new(listen: SocketAddr, extra: &[String]) -> AllowedHosts {
        let mut names: Vec<String> = ["localhost", "127.0.0.1", "::1"]
            .iter()
            .map(|s| (*s).to_owned())
            .collect();
        names.push(listen.ip().to_string());
        names.extend(extra.iter().map(|name| name.trim().to_ascii_lowercase()));
        AllowedHosts(Arc::new(names))
    }

    /// Whether `host` (a Host header value: name or address, with or without port) is one
    /// of ours.
    pub fn allows(&self, host: &str) -> bool {
        let name = host_name(host).to_ascii_lowercase();
        if let Ok(ip) = name.parse::<IpAddr>()
            && ip.is_loopback()
        {
            return true;
        }
        name.ends_with(".localhost") || self.0.contains(&name)
    }
}

/// The name part of a Host header value: `[::1]:8080` → `::1`, `a.b:80` → `a.b`.
fn host_name(host: &str) -> &str {
    if let Some(rest) = host.strip_prefix('[') {
        return rest.split(']').next().unwrap_or(rest);
    }
    match host.rsplit_once(':') {
        Some((name, port)) if port.bytes().all(|b| b.is_ascii_digit()) => name,
        _ => host,
    }
}

/// Refuses with `status` and problem+json of type `tag`.
fn refuse(status: StatusCode, tag: &'static str, message: String) -> Response {
    problem(ApiError::cross_site(tag, message), status)
}

/// The middleware: refuses with 421 (foreign Host, `foreign_host`) or 403 (cross-origin, or
/// a body a web form could send: `cross_site`) and problem+json saying why.
pub async fn guard(State(hosts): State<AllowedHosts>, request: Request, next: Next) -> Response {
    let headers = request.headers();
    let host = headers
        .get(header::HOST)
        .and_then(|v| v.to_str().ok())
        .or_else(|| request.uri().authority().map(|a| a.as_str()))
        .unwrap_or("");
    if !hosts.allows(host) {
        return refuse(
            StatusCode::MISDIRECTED_REQUEST,
            "foreign_host",
            format!("Host {host:?} is not a name of this server; add it with --allowed-host"),
        );
    }
    if let Some(origin) = headers.get(header::ORIGIN) {
        let origin = origin.to_str().unwrap_or("");
        let origin_host = origin.split_once("://").map_or("", |(_, rest)| rest);
        if !host_name(origin_host).eq_ignore_ascii_case(host_name(host)) {
            return refuse(
                StatusCode::FORBIDDEN,
                "cross_site",
                format!("cross-origin request from {origin:?} refused"),
            );
        }
    }
    let reads = [Method::GET, Method::HEAD, Method::OPTIONS];
    if !reads.contains(request.method()) {
        let content_type = headers
            .get(header::CONTENT_TYPE)
            .and_then(|v| v.to_str().ok())
            .unwrap_or("")
            .to_ascii_lowercase();
        let media = content_type.split(';').next().unwrap_or("").trim();
        let typed = media == "application/json"
            || media.ends_with("+json")
            || media == "application/octet-stream";
        let marked =
            headers.contains_key(CLIENT_HEADER) || headers.contains_key("x-requested-with");
        if !typed && !marked {
            return refuse(
                StatusCode::FORBIDDEN,
                "cross_site",
                format!(
                    "{} needs Content-Type: application/json or an X-Ecat-Client header \
                     (browser cross-site request protection)",
                    request.method()
                ),
            );
        }
    }
    next.run(request).await
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hosts_are_loopback_the_listener_and_the_configured_names() {
        let hosts = AllowedHosts::new("10.0.0.5:8080".parse().unwrap(), &["Ecat.Plant".into()]);
        for ok in [
            "localhost",
            "localhost:8080",
            "127.0.0.1:1",
            "127.9.9.9",
            "[::1]:80",
            "10.0.0.5:8080",
            "ecat.plant",
            "ECAT.PLANT:80",
            "ui.localhost",
        ] {
            assert!(hosts.allows(ok), "{ok}");
        }
        for bad in [
            "evil.example",
            "evil.example:8080",
            "",
            "10.0.0.6",
            "localhost.evil",
        ] {
            assert!(!hosts.allows(bad), "{bad}");
        }
    }
}
