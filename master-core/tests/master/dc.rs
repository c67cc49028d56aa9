//! Distributed clocks against the simulator: the measured propagation delays are the
//! simulated per-hop delays, the offsets bring every slave's system time to the
//! reference's, the reference time distributed in each cycle holds drifting clocks
//! together, and SYNC0 is started with the configured cycle.

use crate::master_support;

use std::time::Duration;

use master_core::master::{DcSettings, MasterConfig, SlaveAddress};
use master_core::wire::register::address as reg;
use master_support::{Rig, block_on, rig_on, wait_until};
use sim::esc::DcConfig;
use sim::link::InProcessLink;
use sim::topology::{Topology, build_with_handles};

/// Per-hop delays given to the five slaves (ns).
const HOPS: [u32; 5] = [150, 200, 300, 120, 500];
/// Clock drift of each slave against the time base (ppb): up to ±50 ppm.
const DRIFT: [i32; 5] = [0, 50_000, -30_000, 10_000, -50_000];
/// Simulated time per step of the drift test: one cycle's worth.
const STEP_NS: u64 = 1_000_000;
/// The bound on any slave's system-time difference to the reference while the cycle runs:
/// in one step a clock 50 ppm off the reference (which runs true) moves 50 ns away, and each
/// cycle's reference time pulls it back; twice the 100 ns two such clocks could be apart
/// leaves room for the compensation's rounding.
const BOUND_NS: i64 = 200;

fn rig(config: MasterConfig) -> Rig<InProcessLink> {
    let mut topology = Topology::default_segment();
    for (slave, hop) in topology.slaves.iter_mut().zip(HOPS) {
        slave.esc.hop_delay_ns = hop;
    }
    let built = build_with_handles(&topology).expect("builds");
    let mut segment = built.segment;
    for (p, (hop, drift)) in HOPS.iter().zip(DRIFT).enumerate() {
        // Local clocks started at unrelated moments: offsets have real work to do.
        segment.esc_mut(p).unwrap().set_dc_config(DcConfig {
            hop_delay_ns: *hop,
            clock_start_ns: 7_000_000_000 * p as u64 + 123_457,
            drift_ppb: drift,
        });
    }
    rig_on(
        segment,
        built.time,
        topology,
        MasterConfig {
            watch_interval: None,
            ..config
        },
    )
}

/// System time of every slave at the segment's current instant.
fn system_times(rig: &Rig<InProcessLink>) -> Vec<u64> {
    let segment = rig.segment();
    let now = segment.now_ns();
    (0..segment.len())
        .map(|p| segment.esc(p).unwrap().system_time(now))
        .collect()
}

#[test]
fn measured_delays_are_the_simulated_hops_and_clocks_stay_together() {
    let rig = rig(MasterConfig::default());
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);

    let dc = rig.master().dc_slaves();
    assert_eq!(dc.len(), HOPS.len(), "every simulated ESC has DC");
    assert!(dc[0].reference && dc.iter().skip(1).all(|s| !s.reference));
    let mut expected = 0;
    for (p, slave) in dc.iter().enumerate() {
        if p > 0 {
            expected += HOPS[p];
        }
        // The latch frame reaches slave p after the hops of slaves 1..=p behind the
        // reference (the first hop, master → reference, is common to all).
        assert_eq!(slave.delay_ns, expected, "slave {p}");
        let written = rig
            .segment()
            .esc(p)
            .unwrap()
            .read_u32(reg::DC_SYSTEM_TIME_DELAY);
        assert_eq!(written, expected, "0x0928 of slave {p}");
    }

    // Right after the scan (time has not moved): every clock reads the reference's time.
    let times = system_times(&rig);
    for (p, t) in times.iter().enumerate() {
        assert!(
            (*t as i64 - times[0] as i64).abs() <= BOUND_NS,
            "slave {p} is {} ns off",
            *t as i64 - times[0] as i64
        );
    }

    // Time runs, the clocks drift, every cycle's reference time holds them together.
    // The difference is looked at just before each cycle's correction, when it is largest.
    let mut worst = 0i64;
    for _ in 0..300 {
        rig.time.advance(STEP_NS);
        let times = system_times(&rig);
        for t in &times {
            worst = worst.max((*t as i64 - times[0] as i64).abs());
        }
        let done = rig.master().cycle_stats().completed;
        assert!(wait_until(|| rig.master().cycle_stats().completed > done));
    }
    assert!(worst <= BOUND_NS, "worst difference {worst} ns");
    // Without correction, 300 steps would have moved the ±50 ppm clocks 15 µs apart from
    // the reference; the drift is real, it is just compensated every cycle.
    assert!(worst >= 40, "the clocks drift between cycles ({worst} ns)");
    // The slaves' own difference registers say the same.
    for p in 1..HOPS.len() {
        let raw = rig
            .segment()
            .esc(p)
            .unwrap()
            .read_u32(reg::DC_SYSTEM_TIME_DIFFERENCE);
        let magnitude = i64::from(raw & 0x7FFF_FFFF);
        assert!(magnitude <= BOUND_NS, "0x092C of slave {p}: {magnitude} ns");
    }
    // The cycle reads the reference time: the reference's system time at the frame.
    let reference = rig.master().dc_reference_time().expect("reference time");
    let now = system_times(&rig)[0];
    assert!(now.abs_diff(reference) <= STEP_NS);
    let stats = rig.master().cycle_stats();
    assert_eq!(stats.last_wkc, stats.expected_wkc);
}

#[test]
fn sync0_runs_with_the_configured_cycle_on_slaves_with_process_data() {
    let cycle = Duration::from_micros(500);
    let rig = rig(MasterConfig {
        dc: DcSettings {
            sync0_cycle: Some(cycle),
            ..DcSettings::default()
        },
        ..MasterConfig::default()
    });
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    let times = system_times(&rig);
    for (p, spec) in rig.topology.slaves.iter().enumerate() {
        let esc = rig.segment().esc(p).unwrap().read_u8(reg::DC_ACTIVATION);
        let pd = rig
            .master()
            .slave(SlaveAddress::Position(p as u16))
            .unwrap()
            .process_data;
        let has_pd = pd.outputs + pd.inputs > 0;
        if !has_pd {
            assert_eq!(esc, 0, "{}: no SYNC0 without process data", spec.name);
            continue;
        }
        let segment = rig.segment();
        let e = segment.esc(p).unwrap();
        assert_eq!(esc, 0x03, "{}: cyclic operation + SYNC0", spec.name);
        assert_eq!(
            e.read_u8(reg::DC_CYCLIC_UNIT_CONTROL),
            0,
            "SYNC unit on ECAT"
        );
        assert_eq!(e.read_u32(reg::DC_SYNC0_CYCLE), 500_000);
        let start = e.read_u64(reg::DC_START_TIME);
        assert_eq!(start % 500_000, 0, "first pulse on a cycle boundary");
        // At least the lead (100 ms) ahead of the slave's time when it was set.
        assert!(start >= times[p] + 100_000_000, "{}", spec.name);
        assert!(start <= times[p] + 100_000_000 + 500_000 + 1_000_000);
    }
}

#[test]
fn without_dc_no_clock_is_touched() {
    let rig = rig(MasterConfig {
        dc: DcSettings {
            enabled: false,
            ..DcSettings::default()
        },
        ..MasterConfig::default()
    });
    let report = block_on(rig.master().scan()).expect("scan");
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    assert!(rig.master().dc_slaves().is_empty());
    assert_eq!(rig.master().dc_reference_time(), None);
    for p in 0..HOPS.len() {
        assert_eq!(
            rig.segment()
                .esc(p)
                .unwrap()
                .read_u32(reg::DC_SYSTEM_TIME_DELAY),
            0
        );
    }
}
