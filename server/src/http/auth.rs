//! The REST side of the bearer tokens: every `/api/v1` call is authenticated; methods other
//! than GET and HEAD are writes (write role, audit line).

use axum::extract::{Request, State};
use axum::http::{Method, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use crate::security::{Tokens, authorize_write};

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
    if !matches!(*request.method(), Method::GET | Method::HEAD) {
        let operation = format!("{} {}", request.method(), request.uri().path());
        if let Err(err) = authorize_write(Some(&caller), &operation, "") {
            return err.into_response();
        }
    }
    request.extensions_mut().insert(caller);
    next.run(request).await
}
