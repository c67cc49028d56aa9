//! `ecat config`: the slave configurations, as IgH's `ethercat config` lists them: for each
//! slave the configuration expects (`[[slave]]`, or an ENI file) its alias and position,
//! vendor id and product code, the slave it is attached to and that slave's state; `-v`
//! adds the PDO assignment and the start-up commands. Without `[[slave]]` entries ecatd
//! configures every slave it finds as it is, so each found slave is a configuration of its
//! own. `--toml` prints instead the whole configuration ecatd runs with (the file, the
//! environment and the flags together; `--json` gives `{ "toml": ..., "eni": ... }`).

use proto::v1 as pb;
use serde_json::{Value, json};

use crate::Run;
use crate::failure::Failure;
use crate::out::{Out, out};
use crate::parse::{failed, slave_state_text};
use crate::session::Session;

/// `ecat config`.
#[derive(Debug, clap::Args)]
pub struct Config {
    /// Details: identity, attached slave, PDO assignment, start-up commands.
    #[arg(short, long)]
    pub verbose: bool,
    /// The whole configuration ecatd runs with, as TOML (what `ecat config` printed before
    /// it listed the slave configurations).
    #[arg(long, conflicts_with = "verbose")]
    pub toml: bool,
}

/// One slave configuration.
#[derive(Debug, Clone, PartialEq)]
struct SlaveConfig {
    alias: u32,
    /// The ring position (after the alias, when there is one).
    position: u32,
    /// A station address the configuration names the slave by instead.
    station: Option<u32>,
    vendor_id: Option<u32>,
    product_code: Option<u32>,
    /// The `[[slave.startup]]` tables, as TOML values.
    startup: Vec<toml::Value>,
}

impl Run for Config {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let config = session
            .clients()
            .await?
            .bus
            .get_config(pb::GetConfigRequest {})
            .await
            .map_err(failed)?
            .into_inner();
        if self.toml {
            let human = if config.eni.is_empty() {
                config.toml.clone()
            } else {
                format!(
                    "# slaves and cycle from the ENI file {}\n{}",
                    config.eni, config.toml
                )
            };
            return Ok(out(
                json!({ "toml": config.toml, "eni": config.eni }),
                human,
            ));
        }
        let slaves = session.slaves().await?;
        let configs = match expected(&config.toml)? {
            configs if !configs.is_empty() => configs,
            _ => slaves.iter().map(found).collect(),
        };
        let layout = if self.verbose {
            session
                .clients()
                .await?
                .pd
                .get_layout(pb::GetLayoutRequest {
                    slave: String::new(),
                })
                .await
                .map_err(failed)?
                .into_inner()
                .slaves
        } else {
            Vec::new()
        };
        let mut rows = Vec::new();
        let mut details = Vec::new();
        let mut json = Vec::new();
        for config in &configs {
            let attached = attached(config, &slaves);
            let ident = format!(
                "0x{:08x}/0x{:08x}",
                config.vendor_id.unwrap_or_default(),
                config.product_code.unwrap_or_default()
            );
            let place = match config.station {
                Some(station) => format!("#{station}"),
                None => format!("{}:{}", config.alias, config.position),
            };
            rows.push([
                place,
                ident,
                attached.map_or("-".into(), |s| s.position.to_string()),
                attached.map_or("-".into(), |s| slave_state_text(s).to_owned()),
            ]);
            if self.verbose {
                details.push(detail(config, attached, &layout));
            }
            json.push(json!({
                "alias": config.alias, "position": config.position, "station": config.station,
                "vendor_id": config.vendor_id, "product_code": config.product_code,
                "attached": attached.map(|s| s.position),
                "state": attached.map(slave_state_text),
                "startup": config.startup.iter().map(startup_text).collect::<Vec<_>>(),
            }));
        }
        let human = if self.verbose {
            details.join("\n")
        } else {
            columns(&rows)
        };
        Ok(out(Value::Array(json), human))
    }
}

/// The `[[slave]]` entries of ecatd's effective configuration.
fn expected(text: &str) -> Result<Vec<SlaveConfig>, Failure> {
    let config: toml::Table = text
        .parse()
        .map_err(|err| Failure::other(format!("ecatd's configuration does not parse: {err}")))?;
    let number = |table: &toml::Table, key: &str| {
        table
            .get(key)
            .and_then(toml::Value::as_integer)
            .and_then(|n| u32::try_from(n).ok())
    };
    let Some(slaves) = config.get("slave").and_then(toml::Value::as_array) else {
        return Ok(Vec::new());
    };
    Ok(slaves
        .iter()
        .filter_map(toml::Value::as_table)
        .map(|slave| SlaveConfig {
            alias: number(slave, "alias").unwrap_or_default(),
            position: number(slave, "position").unwrap_or_default(),
            station: number(slave, "station"),
            vendor_id: number(slave, "vendor_id"),
            product_code: number(slave, "product_code"),
            startup: slave
                .get("startup")
                .and_then(toml::Value::as_array)
                .cloned()
                .unwrap_or_default(),
        })
        .collect())
}

/// The configuration ecatd makes of a slave it found without a `[[slave]]` entry.
fn found(slave: &pb::Slave) -> SlaveConfig {
    let identity = slave.identity.unwrap_or_default();
    SlaveConfig {
        alias: 0,
        position: slave.position,
        station: None,
        vendor_id: Some(identity.vendor_id),
        product_code: Some(identity.product_code),
        startup: Vec::new(),
    }
}

/// The slave a configuration is attached to: the one at its place whose identity is the
/// expected one (as IgH attaches a configuration only to a matching slave).
fn attached<'a>(config: &SlaveConfig, slaves: &'a [pb::Slave]) -> Option<&'a pb::Slave> {
    let at = match config.station {
        Some(station) => slaves.iter().find(|s| s.station == station),
        None if config.alias != 0 => {
            let first = slaves.iter().position(|s| s.alias == config.alias)?;
            slaves.get(first + usize::try_from(config.position).ok()?)
        }
        None => slaves.iter().find(|s| s.position == config.position),
    }?;
    let identity = at.identity.unwrap_or_default();
    let matches = config.vendor_id.is_none_or(|v| v == identity.vendor_id)
        && config
            .product_code
            .is_none_or(|p| p == identity.product_code);
    matches.then_some(at)
}

/// IgH's `config -v` block of one configuration.
fn detail(config: &SlaveConfig, attached: Option<&pb::Slave>, layout: &[pb::PdSlave]) -> String {
    let mut lines = vec![
        format!("Alias: {}", config.alias),
        format!("Position: {}", config.position),
    ];
    if let Some(station) = config.station {
        lines.push(format!("Station: {station}"));
    }
    lines.push(format!(
        "Vendor Id: 0x{:08x}",
        config.vendor_id.unwrap_or_default()
    ));
    lines.push(format!(
        "Product code: 0x{:08x}",
        config.product_code.unwrap_or_default()
    ));
    lines.push(match attached {
        Some(s) => format!("Attached slave: {} ({})", s.position, slave_state_text(s)),
        None => "Attached slave: none".into(),
    });
    let sms = attached
        .and_then(|s| layout.iter().find(|l| l.slave == s.position))
        .map(|l| l.sync_managers.as_slice())
        .unwrap_or_default();
    for sm in sms.iter().filter(|sm| !sm.pdos.is_empty()) {
        // Control register bit 2: the master writes; bit 6: the watchdog triggers.
        lines.push(format!(
            "SM{}, Dir: {}, Watchdog: {}",
            sm.index,
            if sm.control_register & 0x04 != 0 {
                "Output"
            } else {
                "Input"
            },
            if sm.control_register & 0x40 != 0 {
                "Enable"
            } else {
                "Disable"
            }
        ));
        for pdo in &sm.pdos {
            lines.push(format!("  PDO 0x{:04x} \"{}\"", pdo.index, pdo.name));
            for e in &pdo.entries {
                lines.push(format!(
                    "    PDO entry 0x{:04x}:{:02x}, {:2} bit",
                    e.index, e.subindex, e.bit_length
                ));
            }
        }
    }
    lines.push("SDO configuration:".into());
    if config.startup.is_empty() {
        lines.push("  None.".into());
    }
    for command in &config.startup {
        lines.push(format!("  {}", startup_text(command)));
    }
    lines.push(String::new());
    lines.join("\n")
}

/// A start-up command in one line: `PS 0x6060:00 = 8 (i8)`, `PS IDN 32 drive 0 = 0x...`.
fn startup_text(command: &toml::Value) -> String {
    let get = |key: &str| command.get(key);
    let int = |key: &str| get(key).and_then(toml::Value::as_integer);
    let transition = get("transition")
        .and_then(toml::Value::as_str)
        .unwrap_or("?");
    let target = match (int("index"), get("idn")) {
        (Some(index), _) => format!("0x{index:04x}:{:02x}", int("subindex").unwrap_or(0)),
        (None, Some(idn)) => format!("IDN {idn} drive {}", int("drive").unwrap_or(0)),
        (None, None) => "?".into(),
    };
    let value = match (get("value"), get("data")) {
        (Some(value), _) => match get("type").and_then(toml::Value::as_str) {
            Some(ty) => format!("{value} ({ty})"),
            None => value.to_string(),
        },
        (None, Some(data)) => data.to_string(),
        (None, None) => String::new(),
    };
    format!("{transition} {target} = {value}")
}

/// Rows as columns two spaces apart.
fn columns(rows: &[[String; 4]]) -> String {
    let widths: Vec<usize> = (0..4)
        .map(|c| rows.iter().map(|r| r[c].len()).max().unwrap_or(0))
        .collect();
    rows.iter()
        .map(|r| {
            r.iter()
                .zip(&widths)
                .map(|(cell, width)| format!("{cell:<width$}"))
                .collect::<Vec<_>>()
                .join("  ")
                .trim_end()
                .to_owned()
        })
        .collect::<Vec<_>>()
        .join("\n")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_expected_slaves_are_read_from_the_effective_configuration() {
        let configs = expected(
            "[[slave]]\nposition = 2\nvendor_id = 2\nproduct_code = 3\n\
             [[slave.startup]]\ntransition = \"PS\"\nindex = 0x6060\nsubindex = 0\n\
             value = 8\ntype = \"i8\"\n[[slave]]\nstation = 1004\n",
        )
        .unwrap();
        assert_eq!(configs.len(), 2);
        assert_eq!(configs[0].position, 2);
        assert_eq!(configs[0].vendor_id, Some(2));
        assert_eq!(
            startup_text(&configs[0].startup[0]),
            "PS 0x6060:00 = 8 (i8)"
        );
        assert_eq!(configs[1].station, Some(1004));
        assert!(expected("cycle = 1").unwrap().is_empty());
    }
}
