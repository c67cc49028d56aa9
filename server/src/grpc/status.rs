//! [`ApiError`] as a gRPC status: the code from
//! [`ErrorKind::grpc`](crate::service::ErrorKind::grpc), the message, and a
//! `google.rpc.ErrorInfo` detail (domain `ecat.v1`, reason = the error's tag in
//! UPPER_SNAKE_CASE, metadata `code` (hex at the protocol's width, `0x06020000`) / `code_text`
//! for the protocol's own error code) and,
//! for an invalid argument, a `google.rpc.BadRequest` naming the field.

use std::collections::HashMap;

use tonic::Status;
use tonic_types::{ErrorDetails, StatusExt};

use crate::service::ApiError;

/// The one mapping of an error to a status: handlers use `?` on core calls.
impl From<ApiError> for Status {
    fn from(err: ApiError) -> Status {
        let mut metadata = HashMap::new();
        if let Some(code) = err.code_hex() {
            metadata.insert("code".to_owned(), code);
            metadata.insert("code_text".to_owned(), err.code_text.clone());
        }
        let mut details = ErrorDetails::with_error_info(err.reason(), "ecat.v1", metadata);
        if let Some(field) = err.field {
            details.add_bad_request_violation(field, err.message.clone());
        }
        Status::with_error_details(err.kind.grpc(), err.message, details)
    }
}

/// Narrows a request field to the width the protocol has, or says which field is too wide.
pub fn narrow<T: TryFrom<u32>>(value: u32, field: &'static str) -> Result<T, Status> {
    T::try_from(value).map_err(|_| {
        Status::from(ApiError::invalid_field(
            field,
            format!("{field} {value:#x} is out of range"),
        ))
    })
}
