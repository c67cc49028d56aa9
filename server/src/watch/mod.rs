//! Watched values (`[[watch]]` in the configuration): CoE entries or SoE IDNs read at their
//! own period by background tasks and exported as gauges, so Prometheus can alert on slave
//! parameters without a script; process-data entries (`pdo`) are read from the last cycle's
//! image when Prometheus scrapes, with no mailbox traffic.
//!
//! One task per watch (at most [`crate::config::watch::MAX_WATCHES`]); each reads through
//! the core (so the reads also count in the per-protocol mailbox metrics), one read at a time, a late tick
//! delayed rather than piled up. A failed read counts in `ecat_watch_read_errors_total` and
//! leaves the last value. No lock is held across an `.await`: the store is updated after
//! each read.
//!
//! Files: `values` (the store and its metric families); the configuration entry is read in
//! [`crate::config::watch`].

pub mod values;

use std::sync::Arc;
use std::time::Duration;

use tokio::task::JoinHandle;

pub use crate::config::watch::{Target, WatchSpec};
use crate::input::value::{self, ValueType};
use crate::service::{ApiError, Core, parse_name};
pub use values::{WatchLabels, WatchValues};

/// A watch ready to run.
struct Watch {
    slave: String,
    target: Target,
    period: Duration,
    /// The type named, or learnt from the slave's SDO Information at the first read.
    value_type: Option<ValueType>,
    slot: usize,
}

/// Starts one task per watch, recording into `values`; the configuration was checked
/// ([`crate::config::watch::check_all`]). Abort the handles to stop.
pub fn start(core: &Core, specs: &[WatchSpec], values: &Arc<WatchValues>) -> Vec<JoinHandle<()>> {
    specs
        .iter()
        .filter_map(|spec| {
            let (Ok(target), Ok(value_type)) = (spec.target(), spec.value_type()) else {
                tracing::error!(slave = %spec.slave, "watch not started: invalid");
                return None;
            };
            let labels = WatchLabels {
                slave: spec.slave.clone(),
                object: target.label(),
                name: spec.name.clone().unwrap_or_default(),
            };
            if let Target::Pdo { index, subindex } = target {
                // Read from the image at scrape time: no task, no mailbox traffic.
                values.add_pdo(labels, index, subindex);
                return None;
            }
            let slot = values.add(labels);
            let watch = Watch {
                slave: spec.slave.clone(),
                target,
                period: Duration::from_millis(spec.period_ms),
                value_type,
                slot,
            };
            Some(tokio::spawn(run(core.clone(), watch, Arc::clone(values))))
        })
        .collect()
}

async fn run(core: Core, mut watch: Watch, values: Arc<WatchValues>) {
    let mut tick = tokio::time::interval(watch.period);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut failing = false;
    loop {
        tick.tick().await;
        match read(&core, &mut watch).await {
            Ok(value) => {
                values.set(watch.slot, value);
                failing = false;
            }
            Err(err) => {
                values.fail(watch.slot);
                // One log line per run of failures, not one per period.
                if !failing {
                    tracing::warn!(slave = %watch.slave, object = %watch.target.label(), %err, "watched value not read");
                }
                failing = true;
            }
        }
    }
}

async fn read(core: &Core, watch: &mut Watch) -> Result<f64, ApiError> {
    // Checked when the configuration was read: this does not fail.
    let slave = parse_name(&watch.slave)?;
    let (data, ty) = match watch.target {
        Target::Sdo { index, subindex } => {
            let ty = match watch.value_type {
                Some(ty) => ty,
                None => {
                    let entry = core.coe_entry(slave, index, subindex).await?;
                    let ty = value::for_data_type(entry.data_type.into());
                    watch.value_type = Some(ty);
                    ty
                }
            };
            let data = core.coe_upload(slave, index, subindex, false).await?;
            (data, Some(ty))
        }
        Target::Pdo { .. } => {
            return Err(ApiError::internal(
                "process-data watches are read at scrape time",
            ));
        }
        Target::Idn { drive, idn } => (
            core.soe_read(slave, drive, idn.raw(), 0).await?,
            watch.value_type,
        ),
    };
    number(ty, &data)
}

/// Sets the process-data watches from the last completed cycle (at scrape time).
pub fn refresh_pdo(core: &Core, values: &WatchValues) {
    use crate::service::process_data::PdValue;
    values.refresh_pdo(|slave, index, subindex| {
        let view = core.process_data(Some(parse_name(slave).ok()?)).ok()?;
        let v = view
            .values
            .iter()
            .find(|v| v.entry.index == index && v.entry.subindex == subindex)?;
        match &v.value {
            PdValue::Bool(b) => Some(f64::from(u8::from(*b))),
            PdValue::Int(i) => Some(*i as f64),
            PdValue::Uint(u) => Some(*u as f64),
            PdValue::Real(r) => Some(*r),
            PdValue::Hex(_) => None,
        }
    });
}

/// The value of `data` as a number: decoded as `ty`, or without a type as an unsigned
/// little-endian integer of 1 to 8 bytes.
fn number(ty: Option<ValueType>, data: &[u8]) -> Result<f64, ApiError> {
    let Some(ty) = ty else {
        if data.is_empty() || data.len() > 8 {
            return Err(ApiError::invalid(format!(
                "{} bytes read: name a type for this watch",
                data.len()
            )));
        }
        let mut bytes = [0u8; 8];
        bytes[..data.len()].copy_from_slice(data);
        return Ok(u64::from_le_bytes(bytes) as f64);
    };
    let text = value::decode(ty, data)?;
    match text.as_str() {
        "true" => Ok(1.0),
        "false" => Ok(0.0),
        _ => text
            .parse()
            .map_err(|_| ApiError::invalid(format!("{text:?} is not a number"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_from_bytes() {
        assert_eq!(number(None, &[0xfd, 0x00]), Ok(253.0));
        assert_eq!(number(Some(ValueType::I16), &[0xff, 0xff]), Ok(-1.0));
        assert_eq!(number(Some(ValueType::Bool), &[1]), Ok(1.0));
        assert_eq!(
            number(Some(ValueType::U32), &0xdead_beefu32.to_le_bytes()),
            Ok(f64::from(0xdead_beefu32))
        );
        assert!(number(None, &[]).is_err());
        assert!(number(None, &[0; 9]).is_err());
        assert!(number(Some(ValueType::U32), &[1, 2]).is_err());
    }
}
