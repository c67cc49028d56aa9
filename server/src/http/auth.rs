//! The REST side of the bearer tokens: every `/api/v1` call is authenticated and needs the
//! role [`crate::roles::REST`] declares for its route (an undeclared route needs the write
//! role); a write is audited.

use axum::extract::{MatchedPath, Request, State};
use axum::http::header;
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use crate::roles::{self, Access};
use crate::security::{Tokens, authorize_write};

/// Where the API's routes are nested; the role table names full paths.
const PREFIX: &str = "/api/v1";

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
    // No matched route: the router answers 404 to any authenticated caller.
    let access = request.extensions().get::<MatchedPath>().map(|matched| {
        let route = matched.as_str();
        let full = if route.starts_with(PREFIX) {
            route.to_owned()
        } else {
            format!("{PREFIX}{route}")
        };
        roles::rest(request.method().as_str(), &full).unwrap_or(Access::Write)
    });
    if access == Some(Access::Write) {
        let operation = format!("{} {}", request.method(), request.uri().path());
        let target = request
            .extensions()
            .get::<MatchedPath>()
            .and_then(|matched| slave_of(matched.as_str(), request.uri().path()))
            .unwrap_or_default();
        if let Err(err) = authorize_write(Some(&caller), &operation, target) {
            return err.into_response();
        }
    }
    crate::audit::note_caller(
        &caller.name,
        &format!("{} {}", request.method(), request.uri().path()),
    );
    request.extensions_mut().insert(caller);
    next.run(request).await
}

/// The slave a write names: the `{slave}` segment of `path` where the route template has
/// it (the audit line's `target`, as gRPC's is the request's `slave` field).
fn slave_of<'a>(template: &str, path: &'a str) -> Option<&'a str> {
    let template = template.strip_prefix(PREFIX).unwrap_or(template);
    let path = path.strip_prefix(PREFIX).unwrap_or(path);
    template
        .split('/')
        .zip(path.split('/'))
        .find_map(|(t, p)| (t == "{slave}").then_some(p))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_target_is_the_slave_the_path_names() {
        let route = "/slaves/{slave}/coe/sdo/{index}/{subindex}";
        assert_eq!(slave_of(route, "/slaves/3/coe/sdo/0x2001/0"), Some("3"));
        assert_eq!(
            slave_of(
                &format!("{PREFIX}{route}"),
                "/slaves/station:1004/coe/sdo/1/0"
            ),
            Some("station:1004")
        );
        assert_eq!(slave_of("/bus/rescan", "/bus/rescan"), None);
    }
}
