//! The Rust clients of ecatd's APIs the request benchmarks time: tonic on the generated
//! `ecat.v1` client (one HTTP/2 connection) and ureq (HTTP/1.1 with keep-alive), each
//! uploading 0x1018:01 from a slave by position.

use proto::v1::bus_service_client::BusServiceClient;
use proto::v1::coe_service_client::CoeServiceClient;
use proto::v1::{GetLogFilterRequest, UploadRequest};

/// One tonic client on one HTTP/2 connection, driven from a current-thread runtime.
pub struct GrpcClient {
    runtime: tokio::runtime::Runtime,
    client: CoeServiceClient<tonic::transport::Channel>,
    bus: BusServiceClient<tonic::transport::Channel>,
}

/// A current-thread runtime to drive a tonic client from, and one HTTP/2 connection to
/// `addr` (`host:port`) on it.
pub fn grpc_channel(addr: &str) -> (tokio::runtime::Runtime, tonic::transport::Channel) {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime");
    let channel = runtime
        .block_on(
            tonic::transport::Endpoint::from_shared(format!("http://{addr}"))
                .expect("URL")
                .connect(),
        )
        .expect("gRPC connects");
    (runtime, channel)
}

impl GrpcClient {
    pub fn new(addr: &str) -> GrpcClient {
        let (runtime, channel) = grpc_channel(addr);
        // Both clients share the one connection: a channel is a handle on it.
        let client = CoeServiceClient::new(channel.clone());
        let bus = BusServiceClient::new(channel);
        GrpcClient {
            runtime,
            client,
            bus,
        }
    }

    /// A call that involves no slave (ecatd's log filter): what the transport alone costs.
    pub fn floor(&mut self) -> String {
        self.runtime
            .block_on(self.bus.get_log_filter(GetLogFilterRequest::default()))
            .expect("GetLogFilter")
            .into_inner()
            .filter
    }

    pub fn upload(&mut self, position: u16) -> Vec<u8> {
        let request = UploadRequest {
            slave: position.to_string(),
            index: 0x1018,
            subindex: 1,
            ..UploadRequest::default()
        };
        self.runtime
            .block_on(self.client.upload(request))
            .expect("upload")
            .into_inner()
            .data
    }
}

/// One HTTP/1.1 agent (keep-alive) against ecatd's REST API.
pub struct RestClient {
    agent: ureq::Agent,
    base: String,
}

impl RestClient {
    pub fn new(base: &str) -> RestClient {
        RestClient {
            agent: ureq::Agent::new_with_defaults(),
            base: base.to_owned(),
        }
    }

    /// `/healthz`, which involves no slave: what the transport alone costs.
    pub fn floor(&mut self) -> String {
        self.agent
            .get(format!("{}/healthz", self.base))
            .call()
            .expect("healthz")
            .body_mut()
            .read_to_string()
            .expect("body")
    }

    pub fn upload(&mut self, position: u16) -> String {
        self.agent
            .get(format!(
                "{}/api/v1/slaves/{position}/coe/sdo/0x1018/1",
                self.base
            ))
            .call()
            .expect("REST upload")
            .body_mut()
            .read_to_string()
            .expect("body")
    }
}
