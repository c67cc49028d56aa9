//! `ecat voe VENDOR_ID VENDOR_TYPE DATA`.

use proto::v1 as pb;
use serde_json::json;

use crate::Run;
use crate::failure::Failure;
use crate::out::{Out, out};
use crate::parse::{failed, num, unhex};
use crate::select::Selection;
use crate::session::Session;

/// `ecat voe`.
#[derive(Debug, clap::Args)]
pub struct Voe {
    /// The slave.
    #[command(flatten)]
    pub select: Selection,
    /// Vendor id.
    pub vendor_id: String,
    /// Vendor type.
    pub vendor_type: String,
    /// Payload, hex.
    pub data: String,
}

impl Run for Voe {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let request = pb::VoeRequest {
            slave: self.select.one(session, "voe").await?,
            vendor_id: num(&self.vendor_id, "vendor id")?,
            vendor_type: num(&self.vendor_type, "vendor type")?,
            data: unhex(&self.data)?,
        };
        let r = session
            .clients()
            .await?
            .voe
            .transfer(request)
            .await
            .map_err(failed)?
            .into_inner();
        Ok(out(
            json!({"vendor_id": r.vendor_id, "vendor_type": r.vendor_type, "data": hex::encode(&r.data)}),
            format!(
                "vendor 0x{:08x} type 0x{:04x}: {}",
                r.vendor_id,
                r.vendor_type,
                hex::encode(&r.data)
            ),
        ))
    }
}
