//! The gRPC side of [`crate::security`]: the interceptor that authenticates every call of
//! the `ecat.v1` services, and [`admit`], with which a handler asks the core to admit its
//! caller before it reads the request ([`crate::service::admission`]).

use tonic::{Request, Status};

use crate::security::{Caller, Tokens};
use crate::service::{Core, Operation, Ticket};

/// The called method's HTTP/2 path (`/package.Service/Method`), put in the request's
/// extensions by [`with_path`] before the interceptor runs (a tonic interceptor sees no
/// URI).
#[derive(Debug, Clone)]
pub struct GrpcPath(pub String);

/// Puts the [`GrpcPath`] into the extensions of `request` (the server's outermost layer).
pub fn with_path<B>(
    mut request: tonic::codegen::http::Request<B>,
) -> tonic::codegen::http::Request<B> {
    let path = GrpcPath(request.uri().path().to_owned());
    request.extensions_mut().insert(path);
    request
}

/// The core's admission of the request's caller for `operation`.
pub fn admit<T>(core: &Core, request: &Request<T>, operation: Operation) -> Result<Ticket, Status> {
    Ok(core.admit(request.extensions().get::<Caller>(), operation)?)
}

/// The interceptor in front of every `ecat.v1` service: authenticates and attaches the
/// [`Caller`].
pub fn grpc_interceptor(
    tokens: Tokens,
) -> impl Fn(Request<()>) -> Result<Request<()>, Status> + Clone {
    move |mut request: Request<()>| {
        let header = request
            .metadata()
            .get("authorization")
            .and_then(|v| v.to_str().ok());
        let caller = tokens.authenticate(header)?;
        let path = request
            .extensions()
            .get::<GrpcPath>()
            .map_or("", |p| p.0.as_str());
        crate::audit::note_caller(&caller.name, path);
        request.extensions_mut().insert(caller);
        Ok(request)
    }
}
