//! Slave selection as IgH's `ethercat` has it: `-p POSITION`, `-a ALIAS`, both (the
//! position counts from the slave with the alias), or any name of the common syntax in `-p`
//! (`station:1004`, `alias:0x777+2`, `0x777:2`). A command for one slave refuses to guess
//! when nothing is selected and the segment has more than one slave.

use crate::failure::Failure;
use crate::parse::num;
use crate::session::Session;

/// The `-p` / `-a` options.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct Selection {
    /// The slave: a position (`3`), `alias:relpos` (`0x777:2`), `station:1004`, `pos:3`,
    /// `alias:0x777`; with `-a`, the position after the slave with that alias.
    #[arg(
        short = 'p',
        long = "position",
        visible_alias = "slave",
        value_name = "SLAVE"
    )]
    pub position: Option<String>,
    /// The slave's alias (IgH's `-a`).
    #[arg(short = 'a', long, value_name = "ALIAS")]
    pub alias: Option<String>,
}

impl Selection {
    /// The slave name the options give, if any.
    pub fn given(&self) -> Result<Option<String>, Failure> {
        Ok(match (&self.alias, &self.position) {
            (None, None) => None,
            (None, Some(name)) => Some(name.clone()),
            (Some(alias), None) => Some(format!("alias:{}", num::<u16>(alias, "alias")?)),
            (Some(alias), Some(position)) => Some(format!(
                "alias:{}+{}",
                num::<u16>(alias, "alias")?,
                num::<u16>(position, "position after the alias")?
            )),
        })
    }

    /// The one slave a command works on: the one selected, or the only slave of the
    /// segment; refused when nothing is selected and the segment has several.
    pub async fn one(&self, session: &mut Session, command: &str) -> Result<String, Failure> {
        if let Some(name) = self.given()? {
            return Ok(name);
        }
        let slaves = session.slaves().await?;
        match slaves.as_slice() {
            [only] => Ok(only.position.to_string()),
            [] => Err(format!("{command}: the segment has no slaves").into()),
            many => Err(format!(
                "{command} works on one slave and the segment has {}: select it with \
                 -p POSITION (or -a ALIAS, -p station:ADDRESS)",
                many.len()
            )
            .into()),
        }
    }
}
