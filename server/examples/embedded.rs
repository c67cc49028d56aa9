//! A control program that owns the EtherCAT master and serves ecatd's management surface
//! from its own process (docs/application.md, "Embedding").
//!
//! It opens the built-in simulated segment, scans it, installs its own cycle code (every
//! cycle the DO8's outputs follow the DI8's inputs, bit by bit) and serves gRPC, REST, the
//! mailbox gateway and the metrics until SIGTERM or SIGINT; then the slaves go to INIT and
//! the program stops its bus.
//!
//! ```sh
//! cargo run -p server --example embedded -- --http-listen 127.0.0.1:8080 --switch 3
//! curl -s localhost:8080/api/v1/slaves/1/sim/outputs    # {"outputs":"04"}
//! ```

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicU8, AtomicU64, Ordering};
use std::time::Duration;

use clap::Parser;
use master_core::bus::{Bus, BusConfig};
use master_core::link::{CaptureHub, CaptureTap};
use master_core::master::{
    CompletedCycle, CycleHook, Master, MasterConfig, MasterError, OutgoingImage, SlaveAddress,
};
use server::config::app::AppSettings;
use server::config::{Config, GatewayListen, GatewaySettings, LogFormat, Segment};
use server::embed::Embedded;
use server::signals::Signals;
use server::sim_hooks::SimHooks;
use sim::link::InProcessLink;
use sim::topology::{Topology, build_with_handles};

#[derive(Parser)]
struct Args {
    /// REST, metrics and dashboard (port 0: any free port; the log says which).
    #[arg(long, env = "ECATD_HTTP_LISTEN", default_value = "127.0.0.1:0")]
    http_listen: SocketAddr,
    /// gRPC.
    #[arg(long, env = "ECATD_GRPC_LISTEN", default_value = "127.0.0.1:0")]
    grpc_listen: SocketAddr,
    /// The ETG.8200 mailbox gateway (UDP).
    #[arg(long, env = "ECATD_GATEWAY_LISTEN", default_value = "127.0.0.1:0")]
    gateway_listen: GatewayListen,
    /// `human` or `json`.
    #[arg(long, default_value = "human")]
    log_format: LogFormat,
    /// Holds the simulated switch on DI8 input N (1 to 8) on: DO8 output N follows it. (The
    /// built-in segment also wires DO8's outputs back to DI8's inputs, as on a test bench,
    /// so a mirrored output then holds itself on, like a latching relay.)
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(1..=8))]
    switch: Option<u8>,
}

/// The program's cycle: DO8 output n = DI8 input n. Runs on the bus thread, so it only
/// copies bits and counts.
struct Mirror {
    /// The layout the bit offsets belong to (a rescan may move them).
    layout: u64,
    /// (input bit, output bit) in the image, channel by channel.
    wires: Vec<(u32, u32)>,
    /// The inputs of the last cycle, bit n for `wires[n]`.
    inputs: AtomicU8,
    cycles: AtomicU64,
}

impl CycleHook for Mirror {
    fn after_receive(&self, cycle: &CompletedCycle<'_>) {
        self.cycles.fetch_add(1, Ordering::Relaxed);
        let mut bits = 0;
        for (n, &(input, _)) in self.wires.iter().enumerate() {
            bits |= u8::from(get_bit(cycle.inputs, input)) << n;
        }
        self.inputs.store(bits, Ordering::Relaxed);
    }

    fn before_send(&self, image: &mut OutgoingImage<'_>) {
        // Offsets of another layout would hit other slaves' outputs.
        if image.layout != self.layout {
            return;
        }
        let bits = self.inputs.load(Ordering::Relaxed);
        for (n, &(_, output)) in self.wires.iter().enumerate() {
            set_bit(image.outputs, output, bits >> n & 1 != 0);
        }
    }
}

fn get_bit(image: &[u8], bit: u32) -> bool {
    image
        .get(bit as usize / 8)
        .is_some_and(|byte| byte >> (bit % 8) & 1 != 0)
}

fn set_bit(image: &mut [u8], bit: u32, on: bool) {
    if let Some(byte) = image.get_mut(bit as usize / 8) {
        let mask = 1 << (bit % 8);
        *byte = if on { *byte | mask } else { *byte & !mask };
    }
}

#[tokio::main]
async fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = Args::parse();
    server::logging::init(args.log_format, "info", None)?;
    // Installed first: a signal during the start-up (the scan) is then a clean shutdown as
    // soon as the servers run, not the end of the process with the slaves in OP.
    let mut signals = Signals::install()?;

    // The segment: the simulator's built-in one (slave 1 a DO8, slave 2 a DI8), behind a
    // capture tap for `ecat pcap`.
    let built = build_with_handles(&Topology::default_segment())?;
    if let Some(n) = args.switch {
        let switch = built.slaves[2]
            .inputs
            .as_ref()
            .ok_or("slave 2 has no inputs")?;
        switch.set_input(u16::from(n - 1), true);
    }
    let sim = SimHooks::new(&built.slaves);
    let capture = CaptureHub::new();
    let link = CaptureTap::new(InProcessLink::new(built.segment), Arc::clone(&capture));
    let (bus, bus_thread) = Bus::start(link, BusConfig::default())?;
    let master = Arc::new(Master::start(bus.clone(), MasterConfig::default())?);

    // Scanned here, so that the entries' bit offsets are known before the hook runs.
    master.scan().await?;
    let layout = master.layout_count();
    let wires = (1..=8)
        .map(|channel| {
            let input = master.entry(SlaveAddress::Position(2), 0x6000, channel)?;
            let output = master.entry(SlaveAddress::Position(1), 0x7000, channel)?;
            Ok((input.bit_offset, output.bit_offset))
        })
        .collect::<Result<Vec<_>, MasterError>>()?;
    let mirror = Arc::new(Mirror {
        layout,
        wires,
        inputs: AtomicU8::new(0),
        cycles: AtomicU64::new(0),
    });
    let hook: Arc<dyn CycleHook> = mirror.clone();
    master.set_cycle_hook(Some(hook));
    let counter = Arc::clone(&mirror);
    tokio::spawn(async move {
        let mut second = tokio::time::interval(Duration::from_secs(1));
        loop {
            second.tick().await;
            let cycles = counter.cycles.load(Ordering::Relaxed);
            tracing::info!(cycles, "mirror running");
        }
    });

    let config = Config {
        // Names the link for the APIs and metrics; the servers never open it.
        segment: Some(Segment::Simulate {
            topology: None,
            ring: false,
        }),
        http_listen: args.http_listen,
        grpc_listen: args.grpc_listen,
        gateway: Some(GatewaySettings {
            listen: args.gateway_listen,
            ..GatewaySettings::default()
        }),
        // Our hook owns the outputs: no application interface, whose hook would replace it.
        app: AppSettings {
            enabled: false,
            ..AppSettings::default()
        },
        ..Config::default()
    };
    let served = Embedded::new(Arc::clone(&master), config)
        .scanned()
        .capture(capture)
        .sim_hooks(sim)
        .serve(async move {
            signals.next().await;
            // As ecatd: a second signal ends the program at once.
            signals.exit_on_next();
        })
        .await;

    // The slaves are in INIT: stop the master, then the bus.
    drop(master);
    bus.shutdown();
    let _ = bus_thread.join();
    Ok(served?)
}
