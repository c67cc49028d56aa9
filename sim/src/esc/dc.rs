//! The distributed clock (spec-notes §esc.dc, §dc): a local clock on the simulated time base,
//! receive-time latches, system time with offset, delay and a bounded-slew correction.
//!
//! - Local time = `clock_start_ns` + time since power-on, plus drift.
//! - A write to 0x0900 latches the local time at which the frame passed port 0 (0x0900,
//!   and 0x0918 for the processing unit) and came back at port 1 (0x0904, if open).
//! - System time (0x0910 read) = local time + offset (0x0920) + the control loop's
//!   correction, taken when the frame passes the slave.
//! - A write to 0x0910 is a reference time: the difference
//!   `(system time − delay 0x0928) − received` moves the correction by at most the speed
//!   counter start (0x0930 & 0x7FFF) ns per write, and its filtered value is shown in
//!   0x092C as sign (bit 31: local ≥ received) and magnitude (KickCAT's model).
//!   A 4-byte write compares the low 32 bits with wrapping arithmetic.

use ecat_wire::register::address as reg;
use ecat_wire::register::dc::SystemTimeDifference;

use super::Esc;
use super::memory::overlaps;

/// ns per second, for drift in parts per billion.
const NS_PER_S: i128 = 1_000_000_000;

/// Clock state that is not in registers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct DcState {
    /// Time base value at power-on.
    power_on_at: u64,
    /// Accumulated control-loop correction of the system time, ns.
    correction: i64,
    /// Filtered system time difference; `None` after a filter reset.
    filtered: Option<i64>,
}

impl DcState {
    /// A clock powered on at `now_ns`.
    pub fn new(now_ns: u64) -> Self {
        DcState {
            power_on_at: now_ns,
            correction: 0,
            filtered: None,
        }
    }
}

impl Esc {
    /// The local clock at time-base instant `at_ns`.
    pub fn local_time(&self, at_ns: u64) -> u64 {
        let elapsed = at_ns.saturating_sub(self.dc.power_on_at);
        let drift = i128::from(elapsed) * i128::from(self.config.dc.drift_ppb) / NS_PER_S;
        self.config
            .dc
            .clock_start_ns
            .wrapping_add(elapsed)
            .wrapping_add_signed(drift as i64)
    }

    /// The system time (local + offset + correction) at time-base instant `at_ns`.
    pub fn system_time(&self, at_ns: u64) -> u64 {
        self.local_time(at_ns)
            .wrapping_add(self.mem.u64(reg::DC_SYSTEM_TIME_OFFSET.into()))
            .wrapping_add_signed(self.dc.correction)
    }

    /// Whether system time and friends are 64 bits wide (feature bit 3).
    fn dc_64bit(&self) -> bool {
        self.config.features.dc_64bit()
    }

    /// Puts the system time at the current frame's passage into 0x0910.
    pub(crate) fn refresh_system_time(&mut self) {
        let now = self.system_time(self.frame.port0_ns);
        let value = if self.dc_64bit() {
            now
        } else {
            now & 0xFFFF_FFFF
        };
        self.mem.set_u64(reg::DC_SYSTEM_TIME.into(), value);
    }

    /// A write to 0x0900: latch the receive times of the current frame.
    pub(crate) fn latch_receive_times(&mut self) {
        let port0 = self.local_time(self.frame.port0_ns);
        self.mem
            .set_u32(reg::DC_RECEIVE_TIME_PORT0.into(), port0 as u32);
        if let Some(port1) = self.frame.port1_ns {
            let port1 = self.local_time(port1);
            self.mem
                .set_u32(reg::DC_RECEIVE_TIME_PORT1.into(), port1 as u32);
        }
        let processing_unit = if self.dc_64bit() {
            port0
        } else {
            port0 & 0xFFFF_FFFF
        };
        self.mem
            .set_u64(reg::DC_RECEIVE_TIME_PROCESSING_UNIT.into(), processing_unit);
    }

    /// A write of `data` at `addr` covered (part of) 0x0910-0x0917: a reference time
    /// arrived.
    pub(crate) fn system_time_written(&mut self, addr: u32, data: &[u8]) {
        let base = u32::from(reg::DC_SYSTEM_TIME);
        let local = self.system_time(self.frame.port0_ns);
        // The received value: the written bytes over the local copy's.
        let mut bytes = local.to_le_bytes();
        for (i, byte) in bytes.iter_mut().enumerate() {
            let a = base + i as u32;
            if let Some(&b) = a.checked_sub(addr).and_then(|off| data.get(off as usize)) {
                *byte = b;
            }
        }
        let received = u64::from_le_bytes(bytes);
        let delay = self.mem.u32(reg::DC_SYSTEM_TIME_DELAY.into());
        let wide = self.dc_64bit() && overlaps(addr, data.len(), base + 4, 4);
        let diff = if wide {
            local.wrapping_sub(u64::from(delay)).wrapping_sub(received) as i64
        } else {
            i64::from(
                (local as u32)
                    .wrapping_sub(delay)
                    .wrapping_sub(received as u32) as i32,
            )
        };
        let step = i64::from(self.mem.u16(reg::DC_SPEED_COUNTER_START.into()) & 0x7FFF).max(1);
        self.dc.correction = self.dc.correction.wrapping_sub(diff.clamp(-step, step));
        let depth = u32::from(self.mem.u8(reg::DC_TIME_FILTER_DEPTH.into()) & 0x0F);
        let filtered = filter(self.dc.filtered, diff, depth);
        self.dc.filtered = Some(filtered);
        self.mem.set_u32(
            reg::DC_SYSTEM_TIME_DIFFERENCE.into(),
            SystemTimeDifference::from_ns(filtered).encode(),
        );
    }

    /// A write to the speed counter start resets the filters (ETG.1000.4, spec-notes §dc).
    pub(crate) fn reset_dc_filter(&mut self) {
        self.dc.filtered = None;
    }
}

/// One step of an exponential average with weight 2^-depth, rounded so that it reaches a
/// constant input exactly.
fn filter(previous: Option<i64>, sample: i64, depth: u32) -> i64 {
    let Some(previous) = previous else {
        return sample;
    };
    let previous = i128::from(previous);
    let sample_wide = i128::from(sample);
    let weight = 1i128 << depth.min(15);
    let next = previous + (sample_wide - previous) / weight;
    let next = if next == previous && previous != sample_wide {
        previous + (sample_wide - previous).signum()
    } else {
        next
    };
    i64::try_from(next).unwrap_or(sample)
}

#[cfg(test)]
mod tests {
    use super::super::test_support::*;
    use super::super::{DcConfig, FrameTiming};
    use super::*;
    use ecat_wire::command::Command;

    #[test]
    fn filter_converges_exactly() {
        let mut f = Some(1000);
        for _ in 0..200 {
            f = Some(filter(f, 0, 4));
        }
        assert_eq!(f, Some(0));
        assert_eq!(filter(None, -5, 4), -5);
        assert_eq!(filter(Some(100), 0, 0), 0, "depth 0: no filtering");
    }

    #[test]
    fn local_time_runs_from_power_on_with_drift() {
        let (mut esc, _) = slave_with(|c| {
            c.dc = DcConfig {
                clock_start_ns: 500,
                drift_ppb: 1000,
                ..DcConfig::default()
            }
        });
        assert_eq!(esc.local_time(1_000_000_000), 500 + 1_000_000_000 + 1000);
        esc.power_cycle(2_000_000_000);
        assert_eq!(esc.local_time(2_000_000_100), 600);
    }

    #[test]
    fn latch_and_system_time() {
        let (mut esc, mut dev) = slave_with(|c| c.dc.clock_start_ns = 10_000);
        esc.frame = FrameTiming {
            port0_ns: 1_000,
            port1_ns: Some(1_300),
        };
        exec(&mut esc, &mut dev, Command::Bwr, 0, 0x0900, &[0; 4]);
        assert_eq!(esc.read_u32(0x0900), 11_000);
        assert_eq!(esc.read_u32(0x0904), 11_300);
        assert_eq!(esc.read_u64(0x0918), 11_000);
        exec(
            &mut esc,
            &mut dev,
            Command::Apwr,
            0,
            0x0920,
            &(-10_000i64).to_le_bytes(),
        );
        let r = exec(&mut esc, &mut dev, Command::Aprd, 0, 0x0910, &[0; 8]);
        assert_eq!(u64::from_le_bytes(r.data.try_into().unwrap()), 1_000);
    }

    #[test]
    fn reference_time_writes_slew_and_report_the_difference() {
        let (mut esc, mut dev) = slave();
        esc.frame = FrameTiming {
            port0_ns: 1_000_000,
            port1_ns: None,
        };
        // Local system time is 1_000_000; the reference says 1_010_000 (we are 10 µs late).
        exec(
            &mut esc,
            &mut dev,
            Command::Apwr,
            0,
            0x0910,
            &1_010_000u64.to_le_bytes(),
        );
        let diff = SystemTimeDifference::decode(esc.read_u32(0x092C));
        assert_eq!(diff.as_ns(), -10_000);
        assert!(!diff.local_ahead);
        assert_eq!(esc.system_time(1_000_000), 1_000_000 + 4096, "bounded slew");
        for _ in 0..3 {
            exec(
                &mut esc,
                &mut dev,
                Command::Apwr,
                0,
                0x0910,
                &1_010_000u32.to_le_bytes(),
            );
        }
        assert_eq!(esc.system_time(1_000_000), 1_010_000);
        exec(&mut esc, &mut dev, Command::Apwr, 0, 0x0930, &[0x00, 0x10]);
        exec(
            &mut esc,
            &mut dev,
            Command::Apwr,
            0,
            0x0910,
            &1_010_000u32.to_le_bytes(),
        );
        assert_eq!(
            esc.read_u32(0x092C),
            0x8000_0000,
            "converged: +0, filter reset"
        );
    }
}
