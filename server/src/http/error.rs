//! [`ApiError`] as an HTTP response: the status from [`ErrorKind::http`](crate::service::ErrorKind::http)
//! and a JSON body with the same fields gRPC carries.

use axum::Json;
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use utoipa::ToSchema;

use crate::service::ApiError;

/// The JSON body of every failed REST call.
#[derive(Debug, Serialize, ToSchema)]
pub struct ErrorBody {
    /// What failed.
    pub error: ErrorInfo,
}

/// What failed.
#[derive(Debug, Serialize, ToSchema)]
pub struct ErrorInfo {
    /// Stable machine-readable tag (`sdo_abort`, `soe_error`, `unknown_slave`, ...).
    pub kind: String,
    /// Human-readable message.
    pub message: String,
    /// The protocol's error code (CoE abort code, SoE/FoE error, AL status code).
    pub code: Option<u32>,
    /// The standard text of `code`.
    pub code_text: Option<String>,
    /// The gRPC status code the same failure has (e.g. 10 ABORTED).
    pub grpc_code: i32,
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let status =
            StatusCode::from_u16(self.kind.http()).unwrap_or(StatusCode::INTERNAL_SERVER_ERROR);
        let body = ErrorBody {
            error: ErrorInfo {
                kind: self.tag.to_owned(),
                grpc_code: self.kind.grpc() as i32,
                code_text: self.code.map(|_| self.code_text.clone()),
                code: self.code,
                message: self.message,
            },
        };
        (status, Json(body)).into_response()
    }
}
