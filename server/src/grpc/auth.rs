//! The gRPC side of [`crate::security`]: the interceptor that authenticates every call of
//! the `ecat.v1` services and checks the role [`crate::roles::GRPC`] declares for its method
//! (an undeclared method needs the write role), and the write check with the slave a request
//! names for the audit line.

use tonic::{Request, Status};

use crate::roles::{self, Access};
use crate::security::{Caller, Role, Tokens, authorize_write};

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

/// The gRPC side of [`authorize_write`].
pub fn require_write<T: SlaveField>(request: &Request<T>, operation: &str) -> Result<(), Status> {
    authorize_write(
        request.extensions().get::<Caller>(),
        operation,
        request.get_ref().slave_field(),
    )
    .map_err(Status::from)
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
        let access = roles::grpc(path).unwrap_or(Access::Write);
        if access == Access::Write && caller.role < Role::Write {
            // Refused here for every write method alike; the handlers' own check logs the
            // audit line of an allowed write with the slave it names.
            authorize_write(Some(&caller), path, "")?;
        }
        crate::audit::note_caller(&caller.name, path);
        request.extensions_mut().insert(caller);
        Ok(request)
    }
}

/// The slave a request names, for the audit line.
pub trait SlaveField {
    /// The slave name, or "" for bus-wide calls.
    fn slave_field(&self) -> &str;
}

macro_rules! slave_field {
    ($($t:ty),* $(,)?) => {$(
        impl SlaveField for $t {
            fn slave_field(&self) -> &str { &self.slave }
        }
    )*};
}

slave_field!(
    proto::v1::RequestStateRequest,
    proto::v1::WriteRegisterRequest,
    proto::v1::ReadWriteRegisterRequest,
    proto::v1::WriteSiiRequest,
    proto::v1::SetAliasRequest,
    proto::v1::DownloadRequest,
    proto::v1::SoeWriteRequest,
    proto::v1::VoeRequest,
    proto::v1::SetIpRequest,
);

impl SlaveField for proto::v1::RescanRequest {
    fn slave_field(&self) -> &str {
        "all"
    }
}

impl SlaveField for proto::v1::SetLogFilterRequest {
    fn slave_field(&self) -> &str {
        "ecatd"
    }
}

impl SlaveField for proto::v1::CaptureRequest {
    fn slave_field(&self) -> &str {
        "all"
    }
}

impl SlaveField for tonic::Streaming<proto::v1::FoeWriteChunk> {
    fn slave_field(&self) -> &str {
        "(stream)"
    }
}

impl SlaveField for tonic::Streaming<proto::v1::WriteWithProgressRequest> {
    fn slave_field(&self) -> &str {
        "(stream)"
    }
}
