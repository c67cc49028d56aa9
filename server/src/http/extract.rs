//! The extractors of every REST handler: axum's `Json`, `Path` and `Query` under the same
//! names, whose refusals answer as every other failed call does, with problem+json and a
//! stable `type` (docs/rest.md, "Errors"), where axum's own answer `text/plain`.
//!
//! | refusal                                  | status | `type` (`urn:ecat:error:…`) |
//! |------------------------------------------|--------|-----------------------------|
//! | body not JSON                            | 400    | `invalid_json`              |
//! | wrong type, missing or unknown field     | 422    | `invalid_body`              |
//! | no `Content-Type: application/json`      | 415    | `unsupported_media_type`    |
//! | body unreadable (cut, over the limit)    | 400/413 | `invalid_body`             |
//! | a path segment of the wrong form         | 400    | `invalid_path`              |
//! | a query parameter of the wrong form      | 400    | `invalid_query`             |
//!
//! The status is the one axum gives each refusal; the detail is axum's text, which names
//! the place (`value: invalid type: integer `6`, expected a string at line 1 column 12`).

use axum::extract::rejection::{JsonRejection, PathRejection, QueryRejection};
use axum::extract::{FromRef, FromRequest, FromRequestParts, Request};
use axum::http::StatusCode;
use axum::http::request::Parts;
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use serde::de::DeserializeOwned;

use super::error::problem;
use crate::security::Caller;
use crate::service::operation::Marker;
use crate::service::{ApiError, Core, Ticket};

/// The core's admission for the operation `O` stands for ([`crate::service::admission`]),
/// of the caller the authentication layer found. A handler of an operation that needs the
/// write role takes it as its first argument: the core admits (or refuses, with the same
/// problem+json as any error) before the path, the query or the body is read.
pub struct Admit<O>(pub Ticket, pub std::marker::PhantomData<fn() -> O>);

impl<O: Marker, S: Send + Sync> FromRequestParts<S> for Admit<O>
where
    Core: FromRef<S>,
{
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, ApiError> {
        let caller = parts.extensions.get::<Caller>();
        Ok(Admit(
            Core::from_ref(state).admit(caller, O::OPERATION)?,
            std::marker::PhantomData,
        ))
    }
}

/// A refused request: the problem and the status axum gives it.
#[derive(Debug)]
pub struct Refusal {
    /// The HTTP status.
    pub status: StatusCode,
    /// The problem (its tag is the `type`).
    pub error: ApiError,
}

impl IntoResponse for Refusal {
    fn into_response(self) -> Response {
        problem(self.error, self.status)
    }
}

impl From<JsonRejection> for Refusal {
    fn from(rejection: JsonRejection) -> Refusal {
        let tag = match &rejection {
            JsonRejection::JsonSyntaxError(_) => "invalid_json",
            JsonRejection::MissingJsonContentType(_) => "unsupported_media_type",
            _ => "invalid_body",
        };
        Refusal {
            status: rejection.status(),
            error: ApiError::invalid_request(tag, rejection.body_text()),
        }
    }
}

impl From<PathRejection> for Refusal {
    fn from(rejection: PathRejection) -> Refusal {
        Refusal {
            status: rejection.status(),
            error: ApiError::invalid_request("invalid_path", rejection.body_text()),
        }
    }
}

impl From<QueryRejection> for Refusal {
    fn from(rejection: QueryRejection) -> Refusal {
        Refusal {
            status: rejection.status(),
            error: ApiError::invalid_request("invalid_query", rejection.body_text()),
        }
    }
}

/// A JSON body in (refused as problem+json) or out (as axum's `Json`).
#[derive(Debug, Clone, Copy, Default)]
pub struct Json<T>(pub T);

impl<T, S> FromRequest<S> for Json<T>
where
    T: DeserializeOwned,
    S: Send + Sync,
{
    type Rejection = Refusal;

    async fn from_request(request: Request, state: &S) -> Result<Self, Refusal> {
        let axum::Json(value) = axum::Json::<T>::from_request(request, state).await?;
        Ok(Json(value))
    }
}

impl<T: Serialize> IntoResponse for Json<T> {
    fn into_response(self) -> Response {
        axum::Json(self.0).into_response()
    }
}

/// Path parameters (refused as problem+json).
#[derive(Debug)]
pub struct Path<T>(pub T);

impl<T, S> FromRequestParts<S> for Path<T>
where
    T: DeserializeOwned + Send,
    S: Send + Sync,
{
    type Rejection = Refusal;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, Refusal> {
        let axum::extract::Path(value) =
            axum::extract::Path::<T>::from_request_parts(parts, state).await?;
        Ok(Path(value))
    }
}

/// Query parameters (refused as problem+json; a name the route does not declare is
/// refused before any handler runs, by [`super::unknown`]).
#[derive(Debug)]
pub struct Query<T>(pub T);

impl<T, S> FromRequestParts<S> for Query<T>
where
    T: DeserializeOwned,
    S: Send + Sync,
{
    type Rejection = Refusal;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, Refusal> {
        let axum::extract::Query(value) =
            axum::extract::Query::<T>::from_request_parts(parts, state).await?;
        Ok(Query(value))
    }
}
