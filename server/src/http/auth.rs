//! The REST side of the bearer tokens: every `/api/v1` call is authenticated here, and the
//! caller goes into the request's extensions. What a caller may do is the core's to decide
//! ([`crate::service::admission`]): a handler of an operation that needs the write role
//! takes an [`Admit`](crate::http::extract::Admit) argument, so the core admits the caller
//! before the handler reads anything else of the request.

use axum::extract::{Request, State};
use axum::http::header;
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use crate::security::Tokens;

/// The middleware; see the [module documentation](self).
pub async fn authenticate(
    State(tokens): State<Tokens>,
    mut request: Request,
    next: Next,
) -> Response {
    let header = request
        .headers()
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok());
    let caller = match tokens.authenticate(header) {
        Ok(caller) => caller,
        Err(err) => return err.into_response(),
    };
    crate::audit::note_caller(
        &caller.name,
        &format!("{} {}", request.method(), request.uri().path()),
    );
    request.extensions_mut().insert(caller);
    next.run(request).await
}
