//! [`ApiError`] as an HTTP response: the status from
//! [`ErrorKind::http`](crate::service::ErrorKind::http) and an RFC 9457 problem details body
//! (`application/problem+json`) with the fields gRPC carries as extension members; the
//! protocol's own error code has its own member, `protocol_code`.

use axum::Json;
use axum::http::header::CONTENT_TYPE;
use axum::http::{HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use utoipa::ToSchema;

use crate::service::ApiError;

/// The body of every failed REST call (RFC 9457 §3).
#[derive(Debug, Serialize, ToSchema)]
pub struct ErrorBody {
    /// The problem type: `urn:ecat:error:<reason>`.
    #[serde(rename = "type")]
    pub problem_type: String,
    /// Short summary of the problem type (the HTTP reason phrase).
    pub title: String,
    /// The HTTP status.
    pub status: u16,
    /// Human-readable message about this occurrence.
    pub detail: String,
    /// Stable machine-readable reason in UPPER_SNAKE_CASE (`SDO_ABORT`, `UNKNOWN_SLAVE`,
    /// ...), the same as the gRPC `google.rpc.ErrorInfo` reason.
    pub reason: String,
    /// The gRPC status code the same failure has (e.g. 5 NOT_FOUND).
    pub grpc_code: i32,
    /// The protocol's error code (CoE abort code, SoE/FoE error, AL status code).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub protocol_code: Option<u32>,
    /// The standard text of `protocol_code`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub protocol_code_text: Option<String>,
    /// The request field at fault, for an invalid argument.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub field: Option<String>,
}

/// RFC 9457 §3's media type.
pub const PROBLEM_JSON: &str = "application/problem+json";

impl ErrorBody {
    /// The problem details of `err` answered with `status`.
    pub fn new(err: ApiError, status: StatusCode) -> ErrorBody {
        ErrorBody {
            problem_type: format!("urn:ecat:error:{}", err.tag),
            title: status.canonical_reason().unwrap_or("Error").to_owned(),
            status: status.as_u16(),
            reason: err.reason(),
            grpc_code: err.kind.grpc() as i32,
            protocol_code_text: err.code.map(|_| err.code_text.clone()),
            protocol_code: err.code,
            field: err.field.map(str::to_owned),
            detail: err.message,
        }
    }
}

/// `err` as a response with `status` rather than the one its class maps to: for the few
/// answers HTTP has a status of its own for (413 for a body over the limit).
pub fn problem(err: ApiError, status: StatusCode) -> Response {
    let mut response = (status, Json(ErrorBody::new(err, status))).into_response();
    response
        .headers_mut()
        .insert(CONTENT_TYPE, HeaderValue::from_static(PROBLEM_JSON));
    response
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let status =
            StatusCode::from_u16(self.kind.http()).unwrap_or(StatusCode::INTERNAL_SERVER_ERROR);
        problem(self, status)
    }
}
