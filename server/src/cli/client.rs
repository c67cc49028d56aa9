//! The gRPC connection: address, optional bearer token on every call.

use proto::v1::bus_service_client::BusServiceClient;
use proto::v1::coe_service_client::CoeServiceClient;
use proto::v1::eoe_service_client::EoeServiceClient;
use proto::v1::foe_service_client::FoeServiceClient;
use proto::v1::gateway_service_client::GatewayServiceClient;
use proto::v1::process_data_service_client::ProcessDataServiceClient;
use proto::v1::soe_service_client::SoeServiceClient;
use proto::v1::voe_service_client::VoeServiceClient;
use tonic::metadata::MetadataValue;
use tonic::service::interceptor::InterceptedService;
use tonic::transport::Channel;
use tonic::{Request, Status};

use crate::failure::Failure;

/// Adds `authorization: Bearer <token>` when a token is given.
#[derive(Clone)]
pub struct Auth(Option<MetadataValue<tonic::metadata::Ascii>>);

impl tonic::service::Interceptor for Auth {
    fn call(&mut self, mut request: Request<()>) -> Result<Request<()>, Status> {
        if let Some(value) = &self.0 {
            request
                .metadata_mut()
                .insert("authorization", value.clone());
        }
        Ok(request)
    }
}

type Svc = InterceptedService<Channel, Auth>;

/// One client per service over one channel.
pub struct Clients {
    /// Bus.
    pub bus: BusServiceClient<Svc>,
    /// CoE.
    pub coe: CoeServiceClient<Svc>,
    /// SoE.
    pub soe: SoeServiceClient<Svc>,
    /// FoE.
    pub foe: FoeServiceClient<Svc>,
    /// VoE.
    pub voe: VoeServiceClient<Svc>,
    /// EoE.
    pub eoe: EoeServiceClient<Svc>,
    /// The mailbox gateway.
    pub gateway: GatewayServiceClient<Svc>,
    /// Process data.
    pub pd: ProcessDataServiceClient<Svc>,
}

/// The URI to connect to: `address` as given with `http://` or `https://`, or `host:port`
/// without a scheme (as grpcurl and IgH users write it), taken as `http://` (`https://` with
/// a CA certificate).
pub fn endpoint_uri(address: &str, tls: bool) -> String {
    let scheme = if tls { "https" } else { "http" };
    match address.split_once("://") {
        Some(("http", rest)) if tls => format!("https://{rest}"),
        Some(_) => address.to_owned(),
        None => format!("{scheme}://{address}"),
    }
}

/// Connects to `address` (`http://host:port`, `https://host:port` or `host:port`); over TLS
/// trusting the CA certificate in `tls_ca` (PEM) when given.
pub async fn connect(
    address: &str,
    token: Option<&str>,
    tls_ca: Option<&std::path::Path>,
) -> Result<Clients, Failure> {
    let address = endpoint_uri(address, tls_ca.is_some());
    let address = address.as_str();
    let mut endpoint = Channel::from_shared(address.to_owned())
        .map_err(|err| format!("bad address {address}: {err}"))?;
    if let Some(path) = tls_ca {
        let pem = std::fs::read(path).map_err(|err| {
            Failure::other(format!(
                "cannot read the CA certificate {}: {err}",
                path.display()
            ))
        })?;
        let tls = tonic::transport::ClientTlsConfig::new()
            .ca_certificate(tonic::transport::Certificate::from_pem(pem));
        endpoint = endpoint
            .tls_config(tls)
            .map_err(|err| format!("TLS: {err}"))?;
    }
    let channel = endpoint.connect().await.map_err(|err| {
        // tonic's transport error names only its kind; its causes say why (refused, ...).
        let mut cause = String::new();
        let mut next = std::error::Error::source(&err);
        while let Some(source) = next {
            let text = format!(": {source}");
            if !cause.ends_with(&text) {
                cause.push_str(&text);
            }
            next = source.source();
        }
        Failure::unreachable(format!("cannot connect to {address}: {err}{cause}"))
    })?;
    let auth = Auth(match token {
        None => None,
        Some(t) => Some(
            format!("Bearer {t}")
                .parse()
                .map_err(|_| "the token has characters a header cannot carry")?,
        ),
    });
    Ok(Clients {
        bus: BusServiceClient::with_interceptor(channel.clone(), auth.clone()),
        coe: CoeServiceClient::with_interceptor(channel.clone(), auth.clone()),
        soe: SoeServiceClient::with_interceptor(channel.clone(), auth.clone()),
        foe: FoeServiceClient::with_interceptor(channel.clone(), auth.clone()),
        voe: VoeServiceClient::with_interceptor(channel.clone(), auth.clone()),
        eoe: EoeServiceClient::with_interceptor(channel.clone(), auth.clone()),
        gateway: GatewayServiceClient::with_interceptor(channel.clone(), auth.clone()),
        pd: ProcessDataServiceClient::with_interceptor(channel, auth),
    })
}
