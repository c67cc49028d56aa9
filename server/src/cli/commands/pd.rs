//! Process data: `pd` (the named entries with their live values; `--watch` follows them,
//! `--force` and `--release` an output) and `pdos` (IgH's: each slave's SyncManagers, the
//! PDOs assigned to them and their entries). Both come from ecatd's `ProcessDataService`,
//! which answers from what the master keeps: neither sends a frame on the bus.

use std::io::{IsTerminal, Write};
use std::time::Duration;

use proto::v1 as pb;
use serde_json::{Value, json};

use crate::Run;
use crate::failure::Failure;
use crate::out::{Out, out, printed};
use crate::parse::{failed, num};
use crate::select::Selection;
use crate::session::Session;

/// `ecat pd`.
#[derive(Debug, clap::Args)]
pub struct Pd {
    /// The slave (every slave when none is selected; `--force` and `--release` need one).
    #[command(flatten)]
    pub select: Selection,
    /// Follow the values: redrawn in place on a terminal; otherwise the table (with
    /// `--json`: one JSON object of the changed entries per line) every INTERVAL in which
    /// something changed. INTERVAL: `250ms`, `1s`, or milliseconds; default 100ms, not below
    /// the cycle period nor 10ms.
    #[arg(
        long,
        value_name = "INTERVAL",
        num_args = 0..=1,
        default_missing_value = "",
        conflicts_with_all = ["force", "release"]
    )]
    pub watch: Option<String>,
    /// Force the output INDEX SUB to VALUE from the next cycle on, until released (write
    /// role; refused while a control program owns the outputs, see `--override`).
    #[arg(long, conflicts_with = "release", requires = "value")]
    pub force: bool,
    /// Release the forced output INDEX SUB; without INDEX SUB every forced output of the
    /// slave (of every slave when none is selected).
    #[arg(long)]
    pub release: bool,
    /// List the forced outputs (of the selected slave, or every slave's): value, who
    /// forced them, when, and whether over a control program's outputs.
    #[arg(long, conflicts_with_all = ["watch", "force", "release"])]
    pub forced: bool,
    /// With `--force`: write over the outputs of the control program that owns them
    /// (audited as such).
    #[arg(long = "override", requires = "force")]
    pub over_owner: bool,
    /// Object index of the output (`--force`, `--release`).
    pub index: Option<String>,
    /// Subindex of the output.
    pub subindex: Option<String>,
    /// The value (`--force`): an integer (decimal or 0x hex), a number for REAL32/REAL64
    /// entries, `true` or `false`.
    #[arg(allow_negative_numbers = true)]
    pub value: Option<String>,
}

/// `ecat pdos`.
#[derive(Debug, clap::Args)]
pub struct Pdos {
    /// The slave (every slave when none is selected).
    #[command(flatten)]
    pub select: Selection,
    /// PDOs only, without their entries.
    #[arg(short, long)]
    pub quiet: bool,
}

impl Run for Pd {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        if self.force {
            return self.force(session).await;
        }
        if self.release {
            return self.release(session).await;
        }
        if self.forced {
            return forced(&self.select, session).await;
        }
        if self.index.is_some() {
            return Err("pd takes INDEX SUB [VALUE] only with --force or --release".into());
        }
        let slave = self.select.given()?.unwrap_or_default();
        if let Some(interval) = &self.watch {
            let interval_ms = interval_ms(interval)?;
            return watch(session, slave, interval_ms).await;
        }
        let values = session
            .clients()
            .await?
            .pd
            .read(pb::ProcessDataReadRequest { slave })
            .await
            .map_err(failed)?
            .into_inner();
        Ok(out(
            values_json(
                values.cycle,
                values.wkc,
                values.expected_wkc,
                &values.entries,
            ),
            table(&values.entries),
        ))
    }
}

impl Pd {
    /// The output the positional arguments name: index and subindex.
    fn output(&self) -> Result<(u32, u32), Failure> {
        let index = self.index.as_deref().ok_or("INDEX is missing")?;
        let subindex = self.subindex.as_deref().ok_or("SUB is missing")?;
        Ok((num(index, "index")?, num(subindex, "subindex")?))
    }

    async fn force(self, session: &mut Session) -> Result<Out, Failure> {
        let slave = self.select.one(session, "pd --force").await?;
        let (index, subindex) = self.output()?;
        let value = force_value(self.value.as_deref().unwrap_or_default())?;
        let forced = session
            .clients()
            .await?
            .pd
            .force(pb::ForceRequest {
                slave,
                index,
                subindex,
                value: Some(value),
                r#override: self.over_owner,
            })
            .await
            .map_err(failed)?
            .into_inner()
            .force
            .unwrap_or_default();
        // A write prints nothing; `--json` shows what is forced now.
        Ok(out(force_json(&forced), ""))
    }

    async fn release(self, session: &mut Session) -> Result<Out, Failure> {
        if self.index.is_none() {
            return self.release_all(session).await;
        }
        let slave = self.select.one(session, "pd --release").await?;
        let (index, subindex) = self.output()?;
        session
            .clients()
            .await?
            .pd
            .release_force(pb::ReleaseForceRequest {
                slave,
                index,
                subindex,
            })
            .await
            .map_err(failed)?;
        Ok(out(json!({"ok": true}), ""))
    }

    /// Releases every forced output of the selected slave, or of every slave: nothing
    /// forced is nothing to do, so running it again is no error.
    async fn release_all(self, session: &mut Session) -> Result<Out, Failure> {
        let position = selected_position(&self.select, session).await?;
        let c = session.clients().await?;
        let forced =
            c.pd.list_forced(pb::ListForcedRequest {})
                .await
                .map_err(failed)?
                .into_inner()
                .forced;
        let mut released = Vec::new();
        for f in forced {
            let entry = f.entry.clone().unwrap_or_default();
            if position.is_some_and(|p| p != entry.slave) {
                continue;
            }
            c.pd.release_force(pb::ReleaseForceRequest {
                slave: entry.slave.to_string(),
                index: entry.index,
                subindex: entry.subindex,
            })
            .await
            .map_err(failed)?;
            released.push(force_json(&f));
        }
        Ok(out(json!({"released": released}), ""))
    }
}

/// The ring position of the slave `select` names (`None`: none is selected), as the forces
/// carry it.
async fn selected_position(
    select: &Selection,
    session: &mut Session,
) -> Result<Option<u32>, Failure> {
    let Some(slave) = select.given()? else {
        return Ok(None);
    };
    let layout = session
        .clients()
        .await?
        .pd
        .get_layout(pb::GetLayoutRequest { slave })
        .await
        .map_err(failed)?
        .into_inner();
    Ok(layout.slaves.first().map(|s| s.slave))
}

/// `pd --forced`: the forced outputs, of the selected slave or of every slave.
async fn forced(select: &Selection, session: &mut Session) -> Result<Out, Failure> {
    let position = selected_position(select, session).await?;
    let forced: Vec<pb::PdForce> = session
        .clients()
        .await?
        .pd
        .list_forced(pb::ListForcedRequest {})
        .await
        .map_err(failed)?
        .into_inner()
        .forced
        .into_iter()
        .filter(|f| position.is_none_or(|p| f.entry.as_ref().is_some_and(|e| e.slave == p)))
        .collect();
    let mut rows = vec![header(&[
        "Slave",
        "Entry",
        "Name",
        "Type",
        "Value",
        "Forced by",
        "Override",
        "Since",
    ])];
    for f in &forced {
        let e = f.entry.clone().unwrap_or_default();
        let raw = raw_of(f.value.as_ref(), e.bit_length);
        rows.push(vec![
            e.slave.to_string(),
            format!("0x{:04x}:{:02x}", e.index, e.subindex),
            e.name.clone(),
            type_text(&e),
            value_text(f.value.as_ref(), &raw),
            f.forced_by.clone(),
            if f.r#override { "yes" } else { "no" }.to_owned(),
            humantime::format_rfc3339_seconds(std::time::UNIX_EPOCH + Duration::from_secs(f.since))
                .to_string(),
        ]);
    }
    let json = Value::Array(forced.iter().map(force_json).collect());
    Ok(out(json, columns(&rows)))
}

/// The bits of a forced value (what the table's hex shows), from the value itself.
fn raw_of(value: Option<&pb::PdValue>, bits: u32) -> Vec<u8> {
    use pb::pd_value::Kind;
    let bytes = (bits as usize).div_ceil(8).clamp(1, 8);
    match value.and_then(|v| v.kind.as_ref()) {
        Some(Kind::IntValue(i)) => i.to_le_bytes()[..bytes].to_vec(),
        Some(Kind::UintValue(u)) => u.to_le_bytes()[..bytes].to_vec(),
        Some(Kind::BytesValue(b)) => b.clone(),
        _ => Vec::new(),
    }
}

/// `--watch`'s interval in milliseconds (0: ecatd's default): `250ms`, `1s`, or a number of
/// milliseconds.
fn interval_ms(text: &str) -> Result<u32, Failure> {
    if text.is_empty() {
        return Ok(0);
    }
    let interval = match text.parse::<u64>() {
        Ok(ms) => Duration::from_millis(ms),
        Err(_) => humantime::parse_duration(text)
            .map_err(|err| format!("--watch {text:?}: {err} (give 250ms, 1s, ...)"))?,
    };
    // Rounded up: ecatd then refuses what is too short rather than being asked for less.
    let ms = interval.as_micros().div_ceil(1000);
    match u32::try_from(ms) {
        Ok(0) => Err(format!("--watch {text:?}: the interval must be at least 1ms").into()),
        Ok(ms) => Ok(ms),
        Err(_) => Err(format!("--watch {text:?}: too long").into()),
    }
}

/// A value to force: `true`/`false`, an integer (decimal or `0x` hex, either with a `-`),
/// else a floating-point number.
fn force_value(text: &str) -> Result<pb::force_request::Value, Failure> {
    use pb::force_request::Value as V;
    match text.to_ascii_lowercase().as_str() {
        "true" => return Ok(V::BoolValue(true)),
        "false" => return Ok(V::BoolValue(false)),
        _ => {}
    }
    let (negative, magnitude) = match text.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, text),
    };
    let whole = match magnitude
        .strip_prefix("0x")
        .or_else(|| magnitude.strip_prefix("0X"))
    {
        Some(hex) => Some(
            u64::from_str_radix(hex, 16).map_err(|_| format!("{text:?} is not a hex number"))?,
        ),
        None => magnitude.parse::<u64>().ok(),
    };
    if let Some(whole) = whole {
        let value = if negative {
            0i64.checked_sub_unsigned(whole)
        } else {
            i64::try_from(whole).ok()
        };
        return value
            .map(V::IntValue)
            .ok_or_else(|| format!("{text} is out of range").into());
    }
    text.parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .map(V::RealValue)
        .ok_or_else(|| {
            format!("{text:?} is not a value: give an integer, a number, true or false").into()
        })
}

/// Follows the values until ecatd ends the stream (its shutdown) or the command is stopped.
async fn watch(session: &mut Session, slave: String, interval_ms: u32) -> Result<Out, Failure> {
    let json = session.json();
    let mut stream = session
        .clients()
        .await?
        .pd
        .watch(pb::ProcessDataWatchRequest { slave, interval_ms })
        .await
        .map_err(failed)?
        .into_inner();
    let terminal = std::io::stdout().is_terminal();
    // Every entry as last seen: a message carries only what changed.
    let mut shown: Vec<pb::PdEntryValue> = Vec::new();
    while let Some(message) = stream.message().await.map_err(failed)? {
        let mut stdout = std::io::stdout().lock();
        let written = if json {
            writeln!(
                stdout,
                "{}",
                values_json(
                    message.cycle,
                    message.wkc,
                    message.expected_wkc,
                    &message.entries
                )
            )
        } else {
            merge(&mut shown, message.entries);
            let block = format!(
                "Cycle {}, WorkingCounter {} of {}\n{}\n",
                message.cycle,
                message.wkc,
                message.expected_wkc,
                table(&shown)
            );
            if terminal {
                // Home and clear, then the table: redrawn in place.
                write!(stdout, "\x1b[H\x1b[2J{block}")
            } else {
                writeln!(stdout, "{block}")
            }
        };
        written
            .and_then(|()| stdout.flush())
            .map_err(|err| Failure::other(format!("standard output: {err}")))?;
    }
    Ok(printed())
}

/// Puts the changed entries in place of their old values (new ones at the end).
fn merge(shown: &mut Vec<pb::PdEntryValue>, changed: Vec<pb::PdEntryValue>) {
    for value in changed {
        match shown.iter_mut().find(|v| v.entry == value.entry) {
            Some(old) => *old = value,
            None => shown.push(value),
        }
    }
}

fn direction(entry: &pb::PdEntry) -> &'static str {
    match pb::PdDirection::try_from(entry.direction) {
        Ok(pb::PdDirection::In) => "in",
        Ok(pb::PdDirection::Out) => "out",
        _ => "",
    }
}

/// A value as JSON: a boolean, an integer, a number, or hex for anything else.
fn value_json(value: Option<&pb::PdValue>) -> Value {
    use pb::pd_value::Kind;
    match value.and_then(|v| v.kind.as_ref()) {
        Some(Kind::BoolValue(b)) => json!(b),
        Some(Kind::IntValue(i)) => json!(i),
        Some(Kind::UintValue(u)) => json!(u),
        Some(Kind::RealValue(r)) => json!(r),
        Some(Kind::BytesValue(b)) => json!(hex::encode(b)),
        None => Value::Null,
    }
}

/// A value as the table shows it: integers as IgH's `upload` does (`0x000f 15`, the hex of
/// the entry's bits).
fn value_text(value: Option<&pb::PdValue>, raw: &[u8]) -> String {
    use pb::pd_value::Kind;
    let bits = || -> String { raw.iter().rev().map(|b| format!("{b:02x}")).collect() };
    match value.and_then(|v| v.kind.as_ref()) {
        Some(Kind::BoolValue(b)) => b.to_string(),
        Some(Kind::IntValue(i)) => format!("0x{} {i}", bits()),
        Some(Kind::UintValue(u)) => format!("0x{} {u}", bits()),
        Some(Kind::RealValue(r)) => r.to_string(),
        Some(Kind::BytesValue(b)) => hex::encode(b),
        None => String::new(),
    }
}

fn entry_json(e: &pb::PdEntry) -> Value {
    json!({"slave": e.slave, "station": e.station, "pdo": e.pdo, "index": e.index,
        "subindex": e.subindex, "name": e.name, "type": e.data_type,
        "bit_offset": e.bit_offset, "bit_length": e.bit_length, "direction": direction(e)})
}

/// The values as REST's `ProcessDataJson` has them.
fn values_json(cycle: u64, wkc: u32, expected_wkc: u32, entries: &[pb::PdEntryValue]) -> Value {
    let entries: Vec<Value> = entries
        .iter()
        .map(|v| {
            let mut e = v.entry.as_ref().map(entry_json).unwrap_or_default();
            e["value"] = value_json(v.value.as_ref());
            e["raw"] = json!(hex::encode(&v.raw));
            if !v.forced_by.is_empty() {
                e["forced_by"] = json!(v.forced_by);
            }
            e
        })
        .collect();
    json!({"cycle": cycle, "wkc": wkc, "expected_wkc": expected_wkc, "entries": entries})
}

fn force_json(f: &pb::PdForce) -> Value {
    let mut e = f.entry.as_ref().map(entry_json).unwrap_or_default();
    e["value"] = value_json(f.value.as_ref());
    e["forced_by"] = json!(f.forced_by);
    e["override"] = json!(f.r#override);
    e["since"] = json!(f.since);
    e
}

fn header(names: &[&str]) -> Vec<String> {
    names.iter().map(|n| (*n).to_owned()).collect()
}

/// The type column: the CoE type, or the bit length when the type is not known.
fn type_text(e: &pb::PdEntry) -> String {
    if e.data_type.is_empty() {
        format!("{} bit", e.bit_length)
    } else {
        e.data_type.clone()
    }
}

/// Rows as lined-up columns, two spaces apart.
fn columns(rows: &[Vec<String>]) -> String {
    let mut widths = vec![0usize; rows.first().map_or(0, Vec::len)];
    for row in rows {
        for (w, cell) in widths.iter_mut().zip(row) {
            *w = (*w).max(cell.chars().count());
        }
    }
    rows.iter()
        .map(|row| {
            let line: Vec<String> = row
                .iter()
                .zip(&widths)
                .map(|(cell, &w)| format!("{cell:w$}"))
                .collect();
            line.join("  ").trim_end().to_owned()
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The entries as a table: slave, index:sub, name, type, direction, value, forced by.
fn table(entries: &[pb::PdEntryValue]) -> String {
    let mut rows = vec![header(&[
        "Slave",
        "Entry",
        "Name",
        "Type",
        "Dir",
        "Value",
        "Forced by",
    ])];
    for v in entries {
        let e = v.entry.clone().unwrap_or_default();
        rows.push(vec![
            e.slave.to_string(),
            format!("0x{:04x}:{:02x}", e.index, e.subindex),
            e.name.clone(),
            type_text(&e),
            direction(&e).to_owned(),
            value_text(v.value.as_ref(), &v.raw),
            v.forced_by.clone(),
        ]);
    }
    columns(&rows)
}

impl Run for Pdos {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let slave = self.select.given()?.unwrap_or_default();
        let layout = session
            .clients()
            .await?
            .pd
            .get_layout(pb::GetLayoutRequest { slave })
            .await
            .map_err(failed)?
            .into_inner();
        // IgH names the slave above its SyncManagers when it lists more than one.
        let headers = layout.slaves.len() > 1;
        let mut human = Vec::new();
        let mut slaves = Vec::new();
        for s in &layout.slaves {
            if headers && !s.sync_managers.is_empty() {
                human.push(format!("=== Master 0, Slave {} ===", s.slave));
            }
            let mut sms = Vec::new();
            for sm in &s.sync_managers {
                human.push(format!(
                    "SM{}: PhysAddr 0x{:04x}, DefaultSize {:4}, ControlRegister 0x{:02x}, Enable {}",
                    sm.index, sm.physical_address, sm.default_size, sm.control_register, sm.enable
                ));
                // Bit 2 of the control byte: the master writes it (an RxPDO).
                let rx = sm.control_register & 0x04 != 0;
                let mut pdos = Vec::new();
                for pdo in &sm.pdos {
                    human.push(format!(
                        "  {}xPDO 0x{:04x} \"{}\"",
                        if rx { "R" } else { "T" },
                        pdo.index,
                        pdo.name
                    ));
                    let mut entries = Vec::new();
                    for e in &pdo.entries {
                        if !self.quiet {
                            human.push(format!(
                                "    PDO entry 0x{:04x}:{:02x}, {:2} bit, \"{}\"",
                                e.index, e.subindex, e.bit_length, e.name
                            ));
                        }
                        entries.push(json!({"index": e.index, "subindex": e.subindex,
                            "bit_length": e.bit_length, "name": e.name}));
                    }
                    pdos.push(json!({"index": pdo.index, "name": pdo.name, "entries": entries}));
                }
                sms.push(json!({"index": sm.index,
                    "physical_start_address": sm.physical_address,
                    "default_size": sm.default_size, "control_register": sm.control_register,
                    "enable": sm.enable & 1 != 0, "pdo_type": if rx { "rx" } else { "tx" },
                    "length": sm.length, "pdos": pdos}));
            }
            slaves.push(json!({"slave": s.slave, "station": s.station, "sync_managers": sms}));
        }
        Ok(out(Value::Array(slaves), human.join("\n")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn force_values_take_integers_hex_negatives_numbers_and_booleans() {
        use pb::force_request::Value as V;
        assert_eq!(force_value("15").unwrap(), V::IntValue(15));
        assert_eq!(force_value("0x0f").unwrap(), V::IntValue(15));
        assert_eq!(force_value("-5").unwrap(), V::IntValue(-5));
        assert_eq!(force_value("-0x10").unwrap(), V::IntValue(-16));
        assert_eq!(force_value("1.5").unwrap(), V::RealValue(1.5));
        assert_eq!(force_value("TRUE").unwrap(), V::BoolValue(true));
        assert_eq!(
            force_value("-9223372036854775808").unwrap(),
            V::IntValue(i64::MIN)
        );
        assert!(force_value("0xffffffffffffffff").is_err());
        assert!(force_value("on").is_err());
        assert!(force_value("inf").is_err());
    }

    #[test]
    fn watch_intervals_are_milliseconds_or_durations() {
        assert_eq!(interval_ms("").unwrap(), 0);
        assert_eq!(interval_ms("250").unwrap(), 250);
        assert_eq!(interval_ms("1s").unwrap(), 1000);
        assert_eq!(interval_ms("500us").unwrap(), 1, "rounded up");
        assert!(interval_ms("0").is_err());
        assert!(interval_ms("soon").is_err());
    }

    #[test]
    fn the_table_lines_up_its_columns() {
        let entry = |index: u32, name: &str| pb::PdEntryValue {
            entry: Some(pb::PdEntry {
                slave: 0,
                index,
                name: name.into(),
                data_type: "UNSIGNED16".into(),
                bit_length: 16,
                direction: pb::PdDirection::Out as i32,
                ..Default::default()
            }),
            value: Some(pb::PdValue {
                kind: Some(pb::pd_value::Kind::UintValue(15)),
            }),
            raw: vec![0x0f, 0x00],
            forced_by: "anonymous".into(),
        };
        let text = table(&[entry(0x6040, "Controlword"), entry(0x607a, "Target")]);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines[1],
            "0      0x6040:00  Controlword  UNSIGNED16  out  0x000f 15  anonymous"
        );
        assert_eq!(lines[0].find("Value"), lines[1].find("0x000f"));
    }
}
