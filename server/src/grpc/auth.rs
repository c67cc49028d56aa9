//! The gRPC side of [`crate::security`]: the interceptor that authenticates every call of
//! the `ecat.v1` services, and the write check with the slave a request names for the audit
//! line.

use tonic::{Request, Status};

use super::status::status;
use crate::security::{Caller, Tokens, authorize_write};

/// The gRPC side of [`authorize_write`].
pub fn require_write<T: SlaveField>(request: &Request<T>, operation: &str) -> Result<(), Status> {
    authorize_write(
        request.extensions().get::<Caller>(),
        operation,
        request.get_ref().slave_field(),
    )
    .map_err(status)
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
        let caller = tokens.authenticate(header).map_err(status)?;
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

impl SlaveField for tonic::Streaming<proto::v1::FoeWriteChunk> {
    fn slave_field(&self) -> &str {
        "(stream)"
    }
}
