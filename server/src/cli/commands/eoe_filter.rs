//! `ecat eoe_filter`: set the EoE address filter of a slave (ETG.1000.6, Set address
//! filter): which frames the slave passes to its device. No MACs: every unicast frame.

use proto::v1 as pb;
use serde_json::json;

use crate::Run;
use crate::failure::Failure;
use crate::out::{Out, out};
use crate::parse::failed;
use crate::select::Selection;
use crate::session::Session;

/// `ecat eoe_filter`.
#[derive(Debug, clap::Args)]
pub struct EoeFilter {
    /// The slave.
    #[command(flatten)]
    pub select: Selection,
    /// MAC addresses whose frames the slave passes (at most 15); none: every unicast frame.
    #[arg(value_name = "MAC")]
    pub macs: Vec<String>,
    /// A filter mask (at most 3; given again for each).
    #[arg(long = "mask", value_name = "MASK")]
    pub masks: Vec<String>,
    /// Do not pass broadcasts.
    #[arg(long)]
    pub no_broadcasts: bool,
}

impl Run for EoeFilter {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let slave = self.select.one(session, "eoe_filter").await?;
        session
            .clients()
            .await?
            .eoe
            .set_address_filter(pb::SetAddressFilterRequest {
                slave,
                macs: self.macs,
                masks: self.masks,
                no_broadcasts: self.no_broadcasts,
            })
            .await
            .map_err(failed)?;
        Ok(out(json!({"ok": true}), ""))
    }
}
