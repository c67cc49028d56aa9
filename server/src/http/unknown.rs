//! What the API does not have, refused as problem+json (docs/call-it.md, "Errors"): an
//! unknown route (404 `unknown_route`), a method a route does not take (405
//! `method_not_allowed`), and a query parameter the route does not declare (400
//! `unknown_query_parameter`: `?intervall=50ms` fails instead of being ignored).
//!
//! A route's query parameters are the ones its `#[utoipa::path]` declares: the OpenAPI
//! document is the one list, read here when the router is built.

use std::collections::{HashMap, HashSet};
use std::sync::Arc;

use axum::extract::{MatchedPath, Request, State};
use axum::http::{Method, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use utoipa::openapi::OpenApi;
use utoipa::openapi::path::{Operation, ParameterIn};

use super::error::problem;
use crate::service::ApiError;

/// Each documented route's query parameter names, by path template (as axum's
/// [`MatchedPath`] spells it: `/api/v1/slaves/{slave}`), then method. Keyed by path first so
/// that a request's lookup borrows its path instead of allocating a key.
#[derive(Debug, Default)]
pub struct QueryNames(HashMap<String, HashMap<Method, HashSet<String>>>);

impl QueryNames {
    /// The names `document` declares, under `prefix` (where the document's paths are
    /// nested).
    pub fn from_document(document: &OpenApi, prefix: &str) -> QueryNames {
        let mut names: HashMap<String, HashMap<Method, HashSet<String>>> = HashMap::new();
        for (path, item) in &document.paths.paths {
            let shared = item.parameters.iter().flatten();
            let operations: [(Method, &Option<Operation>); 5] = [
                (Method::GET, &item.get),
                (Method::PUT, &item.put),
                (Method::POST, &item.post),
                (Method::DELETE, &item.delete),
                (Method::PATCH, &item.patch),
            ];
            for (method, operation) in operations {
                let Some(operation) = operation else { continue };
                let declared = shared
                    .clone()
                    .chain(operation.parameters.iter().flatten())
                    .filter(|p| matches!(p.parameter_in, ParameterIn::Query))
                    .map(|p| p.name.clone())
                    .collect();
                names
                    .entry(format!("{prefix}{path}"))
                    .or_default()
                    .insert(method, declared);
            }
        }
        QueryNames(names)
    }

    /// The first name in `query` that the route `method path` does not declare; `None`
    /// for a route the document does not list (the dashboard, `/metrics`).
    /// Names are compared decoded, as the route's `Query` reads them (`%72aw` is `raw`).
    fn unknown(&self, method: &Method, path: &str, query: &str) -> Option<String> {
        // HEAD is answered by the GET route.
        let method = if method == Method::HEAD {
            &Method::GET
        } else {
            method
        };
        let declared = self.0.get(path)?.get(method)?;
        form_urlencoded::parse(query.as_bytes())
            .map(|(name, _)| name)
            .find(|name| !declared.contains(name.as_ref()))
            .map(std::borrow::Cow::into_owned)
    }
}

/// The middleware (on each route, after routing): refuses a query parameter the route does
/// not declare.
pub async fn known_query(
    State(names): State<Arc<QueryNames>>,
    request: Request,
    next: Next,
) -> Response {
    let path = request
        .extensions()
        .get::<MatchedPath>()
        .map(MatchedPath::as_str);
    if let (Some(path), Some(query)) = (path, request.uri().query())
        && let Some(name) = names.unknown(request.method(), path, query)
    {
        let message = format!(
            "{} {path} has no query parameter {name:?}",
            request.method()
        );
        return ApiError::invalid_request("unknown_query_parameter", message).into_response();
    }
    next.run(request).await
}

/// The fallback: a path no route serves.
pub async fn route(request: Request) -> Response {
    let message = format!("no route {} {}", request.method(), request.uri().path());
    ApiError::unknown_route("unknown_route", message).into_response()
}

/// A route that exists, with a method it does not take.
pub async fn method(request: Request) -> Response {
    let message = format!(
        "{} does not take {}",
        request.uri().path(),
        request.method()
    );
    problem(
        ApiError::unknown_route("method_not_allowed", message),
        StatusCode::METHOD_NOT_ALLOWED,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use utoipa::openapi::path::{HttpMethod, OperationBuilder, ParameterBuilder, PathsBuilder};
    use utoipa::openapi::{OpenApiBuilder, PathItem};

    fn document() -> OpenApi {
        let query = |name: &str| {
            ParameterBuilder::new()
                .name(name)
                .parameter_in(ParameterIn::Query)
                .build()
        };
        let path = ParameterBuilder::new()
            .name("slave")
            .parameter_in(ParameterIn::Path)
            .build();
        let get = OperationBuilder::new()
            .parameters(Some([path, query("raw")]))
            .build();
        let put = OperationBuilder::new().build();
        OpenApiBuilder::new()
            .paths(
                PathsBuilder::new()
                    .path("/slaves/{slave}", PathItem::new(HttpMethod::Get, get))
                    .path("/master", PathItem::new(HttpMethod::Put, put)),
            )
            .build()
    }

    #[test]
    fn only_the_declared_query_names_pass() {
        let names = QueryNames::from_document(&document(), "/api/v1");
        let slave = "/api/v1/slaves/{slave}";
        assert_eq!(names.unknown(&Method::GET, slave, "raw=true"), None);
        assert_eq!(names.unknown(&Method::HEAD, slave, "raw"), None);
        assert_eq!(
            names
                .unknown(&Method::GET, slave, "raw=1&slave=2")
                .as_deref(),
            Some("slave")
        );
        // A percent-encoded name is the name it encodes, as the route's `Query` reads it.
        assert_eq!(names.unknown(&Method::GET, slave, "%72aw=1"), None);
        assert_eq!(
            names.unknown(&Method::GET, slave, "r%61x=1").as_deref(),
            Some("rax")
        );
        assert_eq!(names.unknown(&Method::GET, slave, "&&"), None);
        assert_eq!(
            names
                .unknown(&Method::PUT, "/api/v1/master", "force=1")
                .as_deref(),
            Some("force")
        );
        assert_eq!(
            names.unknown(&Method::GET, "/metrics", "x=1"),
            None,
            "not documented"
        );
    }
}
