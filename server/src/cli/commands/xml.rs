//! `ecat xml`: an ESI fragment generated from each selected slave's SII (IgH's `xml`).

use proto::v1 as pb;
use serde_json::{Value, json};

use crate::Run;
use crate::esi;
use crate::failure::Failure;
use crate::out::{Out, out};
use crate::parse::failed;
use crate::select::Selection;
use crate::session::Session;

/// `ecat xml`.
#[derive(Debug, clap::Args)]
pub struct Xml {
    /// The slave (every slave when none is selected).
    #[command(flatten)]
    pub select: Selection,
}

impl Run for Xml {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let names: Vec<String> = match self.select.given()? {
            Some(name) => vec![name],
            None => session
                .slaves()
                .await?
                .iter()
                .map(|s| s.position.to_string())
                .collect(),
        };
        let c = session.clients().await?;
        let (mut human, mut json) = (Vec::new(), Vec::new());
        for slave in names {
            let image = c
                .bus
                .read_sii(pb::ReadSiiRequest {
                    slave: slave.clone(),
                })
                .await
                .map_err(failed)?
                .into_inner()
                .data;
            let xml = esi::from_sii(&image, &format!("Slave {slave}"))
                .map_err(|err| format!("slave {slave}: {err}"))?;
            json.push(json!({"slave": slave, "xml": xml}));
            human.push(xml);
        }
        Ok(out(Value::Array(json), human.join("\n")))
    }
}
