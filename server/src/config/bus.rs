//! `[bus]`: the cycle, the bus thread's scheduling, frame timeout and retries, the state
//! the slaves are brought to, the SyncManager watchdog, and what a topology mismatch
//! holds back.

use std::time::Duration;

use serde::{Deserialize, Serialize};

use master_core::bus::{BusConfig, ThreadPriority};
use master_core::master::{MasterConfig, MismatchPolicy, Watchdog};
use master_core::wire::register::AlState;

use super::duration;

/// The state the scan brings the slaves to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum TargetState {
    /// INIT.
    Init,
    /// PREOP: mailboxes only.
    Preop,
    /// SAFEOP: inputs exchanged, outputs safe.
    Safeop,
    /// OP.
    #[default]
    Op,
}

impl TargetState {
    /// The AL state.
    pub fn al_state(self) -> AlState {
        match self {
            TargetState::Init => AlState::Init,
            TargetState::Preop => AlState::PreOp,
            TargetState::Safeop => AlState::SafeOp,
            TargetState::Op => AlState::Op,
        }
    }
}

/// What a slave that is not the one configured (or missing) holds back.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum OnMismatch {
    /// That slave stays in PREOP.
    #[default]
    Slave,
    /// Every slave stays in PREOP.
    Segment,
    /// ecatd does not start (no slave leaves INIT).
    Stop,
}

impl OnMismatch {
    /// The master's policy.
    pub fn policy(self) -> MismatchPolicy {
        match self {
            OnMismatch::Slave => MismatchPolicy::Slave,
            OnMismatch::Segment => MismatchPolicy::Segment,
            OnMismatch::Stop => MismatchPolicy::Stop,
        }
    }
}

/// `[bus.watchdog]`: the SyncManager (process-data) watchdog of every slave with process
/// data (ETG.1000.4 §6.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WatchdogSettings {
    /// Time without process data after which a slave takes its outputs to their safe
    /// state; `"0s"`: off.
    #[serde(with = "duration")]
    pub process_data: Duration,
    /// Watchdog divider (one tick = (divider + 2) × 40 ns); default 2498, 100 µs ticks.
    #[serde(default = "default_divider")]
    pub divider: u16,
}

fn default_divider() -> u16 {
    2498
}

impl WatchdogSettings {
    /// The register values, checked.
    pub fn watchdog(&self) -> Result<Watchdog, String> {
        let tick = (u64::from(self.divider) + 2) * 40;
        let ticks = duration::nanos(self.process_data).div_ceil(tick);
        let process_data_ticks = u16::try_from(ticks).map_err(|_| {
            format!(
                "[bus.watchdog] process_data = {:?} is more than 65535 ticks of {tick} ns; raise divider",
                duration::show(self.process_data)
            )
        })?;
        Ok(Watchdog {
            divider: self.divider,
            process_data_ticks,
        })
    }
}

/// `[bus]`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BusSettings {
    /// Period of the cyclic exchange (default `"1ms"`).
    #[serde(with = "duration")]
    pub cycle: Duration,
    /// `SCHED_FIFO` priority (1-99) of the bus thread; absent: ordinary scheduling.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rt_priority: Option<u8>,
    /// CPU the bus thread is pinned to; absent: any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cpu: Option<usize>,
    /// How long before each cycle the bus thread wakes to spin until it is due, at most
    /// half the cycle (default `"0s"`: none; `BusConfig::cycle_spin`).
    #[serde(with = "duration")]
    pub cycle_spin: Duration,
    /// How long a frame may be away before it is sent again (default `"10ms"`).
    #[serde(with = "duration")]
    pub frame_timeout: Duration,
    /// How many times a lost frame is sent again (default 3).
    pub retries: u32,
    /// The state the slaves are brought to at start (default `op`).
    pub target_state: TargetState,
    /// What a slave other than the one configured (or a missing one) holds back
    /// (default `slave`; `stop` with an ENI file).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub on_mismatch: Option<OnMismatch>,
    /// Report slaves that no `[[slave]]` entry names (when there are entries).
    pub report_extra: bool,
    /// The SyncManager watchdog; absent: the slaves' own.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub watchdog: Option<WatchdogSettings>,
    /// Cable redundancy: the second interface the segment's far end comes back into (a
    /// ring, docs/redundancy.md); absent: a line on the primary interface only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub backup_iface: Option<String>,
}

impl Default for BusSettings {
    fn default() -> BusSettings {
        let bus = BusConfig::default();
        BusSettings {
            cycle: MasterConfig::default().cycle_period,
            rt_priority: None,
            cpu: None,
            cycle_spin: bus.cycle_spin,
            frame_timeout: bus.response_timeout,
            retries: bus.retries,
            target_state: TargetState::Op,
            on_mismatch: None,
            report_extra: true,
            watchdog: None,
            backup_iface: None,
        }
    }
}

impl BusSettings {
    /// Checks the values that TOML's types do not.
    pub fn check(&self) -> Result<(), String> {
        if self.cycle < master_core::bus::MIN_PERIOD {
            return Err(format!(
                "[bus] cycle = {:?} is shorter than the shortest the bus runs, {:?}",
                duration::show(self.cycle),
                duration::show(master_core::bus::MIN_PERIOD)
            ));
        }
        if self.rt_priority.is_some_and(|p| !(1..=99).contains(&p)) {
            return Err("[bus] rt_priority must be 1 to 99".into());
        }
        if self.cycle_spin > self.cycle / 2 {
            return Err(format!(
                "[bus] cycle_spin = {:?} is more than half the cycle ({:?})",
                duration::show(self.cycle_spin),
                duration::show(self.cycle)
            ));
        }
        if self.frame_timeout.is_zero() {
            return Err("[bus] frame_timeout must be more than 0".into());
        }
        if let Some(watchdog) = &self.watchdog {
            watchdog.watchdog()?;
        }
        Ok(())
    }

    /// The bus's configuration.
    pub fn bus_config(&self) -> BusConfig {
        BusConfig {
            response_timeout: self.frame_timeout,
            retries: self.retries,
            priority: self
                .rt_priority
                .map_or(ThreadPriority::Inherit, ThreadPriority::Realtime),
            cycle_spin: self.cycle_spin,
            ..BusConfig::default()
        }
    }

    /// The master's configuration (the DC defaults: SYNC0 is per slave).
    pub fn master_config(&self) -> MasterConfig {
        MasterConfig {
            cycle_period: self.cycle,
            target_state: self.target_state.al_state(),
            ..MasterConfig::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bus(text: &str) -> BusSettings {
        toml::from_str(text).unwrap()
    }

    #[test]
    fn the_cycle_spin_reaches_the_bus_and_is_at_most_half_the_cycle() {
        assert_eq!(
            BusSettings::default().bus_config().cycle_spin,
            Duration::ZERO
        );
        let spun = bus("cycle_spin = \"50us\"");
        spun.check().unwrap();
        assert_eq!(spun.bus_config().cycle_spin, Duration::from_micros(50));
        let half = bus("cycle = \"250us\"\ncycle_spin = \"125us\"");
        half.check().unwrap();
        let over = bus("cycle = \"250us\"\ncycle_spin = \"126us\"");
        let err = over.check().unwrap_err();
        assert!(
            err.contains("cycle_spin") && err.contains("half the cycle"),
            "{err}"
        );
        assert!(toml::from_str::<BusSettings>("cycle_spin = 50").is_err());
    }
}
