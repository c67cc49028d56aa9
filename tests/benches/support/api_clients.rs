//! The Rust clients of ecatd's APIs the request benchmarks time: tonic on the generated
//! `ecat.v1` client (one HTTP/2 connection) and ureq (HTTP/1.1 with keep-alive), each
//! uploading 0x1018:01 from a slave by position.

use proto::v1::UploadRequest;
use proto::v1::coe_service_client::CoeServiceClient;

/// One tonic client on one HTTP/2 connection, driven from a current-thread runtime.
pub struct GrpcClient {
    runtime: tokio::runtime::Runtime,
    client: CoeServiceClient<tonic::transport::Channel>,
}

impl GrpcClient {
    pub fn new(addr: &str) -> GrpcClient {
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .expect("runtime");
        let client = runtime
            .block_on(CoeServiceClient::connect(format!("http://{addr}")))
            .expect("gRPC connects");
        GrpcClient { runtime, client }
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
