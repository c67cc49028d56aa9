//! `ecat-sim`: an emulated EtherCAT segment answering on a network interface.
//!
//! ```text
//! ecat-sim --iface <ifname> [--backup-iface <ifname>] [--topology FILE] [--slaves N] [--pcap FILE]
//!         [--busy-poll] [--spin-us N] [--control] [--loss FRACTION [--loss-seed N]]
//!         [--eoe-tap NAME [--eoe-slave POSITION]]
//! ```
//!
//! Prints one line per emulated slave, then `ecat-sim: ready on <ifname>` on stdout (scripts
//! and tests wait for that line), then a frame counter on stderr about once per second.
//! With `--backup-iface`, the segment is a ring (cable redundancy) from `--iface`, the
//! master's primary port, back to the backup interface (`frontend::ring`). With
//! `--control`, digital outputs are reported and inputs, emergencies, power cycles, cut
//! cables and dead slaves taken as commands on the standard streams (see
//! `frontend::control`). With `--eoe-tap`, an EoE
//! slave's Ethernet side is a TAP interface in ecat-sim's namespace (`frontend::eoe_tap`).
//! SIGINT or SIGTERM end it cleanly (the capture is flushed). Exit codes: 0 after a signal,
//! 1 for a link or capture failure, 2 for bad arguments or a bad topology.

mod frontend;

use std::io::{self, Write};
use std::os::fd::AsRawFd;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use clap::Parser;
use ecat_link::{FaultConfig, FaultInjector, Link, PcapTap, RawSocket, RawSocketOptions};
use sim::device::eoe::HostPort;
use sim::topology::{Built, Topology, build_with_handles};

use frontend::changes::Changes;
use frontend::control::Wiring;
use frontend::counter::FrameCounter;
use frontend::describe::slave_lines;
use frontend::eoe_tap::TapBridge;
use frontend::ring::{PollFds, serve_ring};
use frontend::serve::serve;

/// Emulated EtherCAT slaves on a network interface (raw Ethernet; needs CAP_NET_RAW).
#[derive(Debug, Parser)]
#[command(name = "ecat-sim", version)]
struct Args {
    /// Network interface to answer EtherCAT frames on (e.g. a veth end).
    #[arg(long, value_name = "IFNAME")]
    iface: String,
    /// The master's backup port (cable redundancy): the segment becomes a ring from
    /// `--iface` through every slave back to this interface, whatever the topology says.
    #[arg(long, value_name = "IFNAME")]
    backup_iface: Option<String>,
    /// Segment description (TOML); default: the built-in five-slave segment.
    #[arg(long, value_name = "FILE", conflicts_with = "slaves")]
    topology: Option<PathBuf>,
    /// Instead of a topology: N slaves, the built-in segment's slaves repeated.
    #[arg(long, value_name = "N")]
    slaves: Option<usize>,
    /// Record every frame in and out to this pcap file (with `--backup-iface`: the frames
    /// of the primary port only).
    #[arg(long, value_name = "FILE")]
    pcap: Option<PathBuf>,
    /// Spin on the socket instead of sleeping in poll: lower latency, one busy core.
    #[arg(long)]
    busy_poll: bool,
    /// After answering a frame, spin this many microseconds for the next one before
    /// sleeping in poll: a master's next frame (the read after a mailbox write, say) is then
    /// taken without a wake-up, at the price of that much CPU per frame.
    #[arg(long, value_name = "MICROSECONDS", default_value = "0")]
    spin_us: u32,
    /// Report digital outputs on stdout and take `input`/`emergency`/`power-cycle`/`break`/
    /// `kill`/`heal` commands on stdin.
    #[arg(long)]
    control: bool,
    /// Lose this fraction of the frames (0.0 to 1.0), half of it on the way in and half on
    /// the way out, so that about this fraction of the master's round trips fail: a bad
    /// cable, repeatably (see `--loss-seed`).
    #[arg(long, value_name = "FRACTION", default_value = "0", value_parser = loss_fraction)]
    loss: f64,
    /// Seed of the loss's random choices (the same seed and traffic lose the same frames).
    #[arg(long, value_name = "N", default_value = "1")]
    loss_seed: u64,
    /// Bridge an EoE slave's Ethernet side to a new TAP interface NAME in this network
    /// namespace: the Linux stack here becomes the device behind the slave (run `iperf3 -s`
    /// or any server here). Set IP parameter from the master puts its MAC and IPv4
    /// address/mask on the TAP.
    #[arg(long, value_name = "NAME")]
    eoe_tap: Option<String>,
    /// The ring position of the slave `--eoe-tap` bridges (default: the first EoE slave).
    #[arg(long, value_name = "POSITION", requires = "eoe_tap")]
    eoe_slave: Option<usize>,
}

fn loss_fraction(text: &str) -> Result<f64, String> {
    let value: f64 = text
        .parse()
        .map_err(|_| format!("{text:?} is not a number"))?;
    if (0.0..=1.0).contains(&value) {
        Ok(value)
    } else {
        Err(format!("{value} is not between 0 and 1"))
    }
}

/// Why the simulator stopped with an error, and the exit code that goes with it.
enum Failure {
    /// Bad topology (exit code 2, like a usage error).
    Topology(String),
    /// Link or capture failure (exit code 1).
    Io(String),
}

fn main() -> ExitCode {
    let args = Args::parse();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure::Topology(message)) => {
            eprintln!("ecat-sim: {message}");
            ExitCode::from(2)
        }
        Err(Failure::Io(message)) => {
            eprintln!("ecat-sim: {message}");
            ExitCode::from(1)
        }
    }
}

fn load_topology(args: &Args) -> Result<Topology, Failure> {
    if let Some(count) = args.slaves {
        return Ok(Topology::repeated(count));
    }
    let Some(path) = &args.topology else {
        return Ok(Topology::default_segment());
    };
    let text = std::fs::read_to_string(path).map_err(|err| {
        Failure::Topology(format!("cannot read topology {}: {err}", path.display()))
    })?;
    Topology::from_toml(&text)
        .map_err(|err| Failure::Topology(format!("bad topology {}: {err}", path.display())))
}

fn run(args: &Args) -> Result<(), Failure> {
    let topology = load_topology(args)?;
    if topology.slaves.is_empty() {
        return Err(Failure::Topology("the topology has no slaves".into()));
    }
    let built = build_with_handles(&topology)
        .map_err(|err| Failure::Topology(format!("cannot build the topology: {err}")))?;
    let bridged = bridged_slave(args, &built)?;
    let options = RawSocketOptions {
        busy_poll: args.busy_poll,
        spin: std::time::Duration::from_micros(u64::from(args.spin_us)),
        ..RawSocketOptions::default()
    };
    let socket =
        RawSocket::open(&args.iface, options).map_err(|err| Failure::Io(err.to_string()))?;
    let primary_fd = socket.as_raw_fd();
    // Lost frames are lost before the capture sees them, as on a cable before the slave.
    let faults = FaultConfig {
        drop_tx: args.loss / 2.0,
        drop_rx: args.loss / 2.0,
        ..FaultConfig::default()
    };
    let socket = FaultInjector::new(socket, faults, args.loss_seed);
    let backup = match &args.backup_iface {
        Some(name) => {
            let raw = RawSocket::open(name, options).map_err(|err| Failure::Io(err.to_string()))?;
            let waiter = PollFds::new(primary_fd, raw.as_raw_fd());
            // Its own seed: the two cables do not lose the same frames.
            let link = FaultInjector::new(raw, faults, args.loss_seed.wrapping_add(1));
            Some(Backup { link, waiter })
        }
        None => None,
    };

    // Registered before the ready line, so a signal sent right after it is never lost.
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, Arc::clone(&stop))
            .map_err(|err| Failure::Io(format!("cannot handle signal {signal}: {err}")))?;
    }

    let bridge = match (&args.eoe_tap, &bridged) {
        (Some(name), Some((_, port))) => Some(
            TapBridge::start(name, port, &stop)
                .map_err(|err| Failure::Io(format!("cannot make the TAP {name}: {err}")))?,
        ),
        _ => None,
    };
    let served = match &args.pcap {
        Some(path) => PcapTap::create(socket, path)
            .map_err(|err| Failure::Io(err.to_string()))
            .and_then(|mut tap| {
                let counter = announce_and_serve(
                    &mut tap,
                    backup,
                    args,
                    &topology,
                    built,
                    Arc::clone(&stop),
                )?;
                tap.flush()
                    .map_err(|err| Failure::Io(format!("{}: {err}", path.display())))?;
                Ok(counter)
            }),
        None => {
            let mut socket = socket;
            announce_and_serve(
                &mut socket,
                backup,
                args,
                &topology,
                built,
                Arc::clone(&stop),
            )
        }
    };
    // The loop is over (a signal or an error): the bridge's threads end with it.
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    if let Some(bridge) = bridge {
        bridge.stop();
    }
    let counter = served?;
    if let (Some(name), Some((_, port))) = (&args.eoe_tap, &bridged) {
        let drops = port.drops();
        eprintln!(
            "ecat-sim: {name}: frames dropped to the TAP {} to the master {}",
            drops.to_host, drops.to_master
        );
    }
    eprintln!(
        "ecat-sim: stopped; frames in {} out {}",
        counter.frames_in, counter.frames_out
    );
    Ok(())
}

/// The slave `--eoe-tap` bridges and its host port: the one at `--eoe-slave`, else the
/// first EoE slave.
fn bridged_slave(args: &Args, built: &Built) -> Result<Option<(usize, HostPort)>, Failure> {
    if args.eoe_tap.is_none() {
        return Ok(None);
    }
    let port_at = |position: usize| {
        built
            .slaves
            .get(position)
            .and_then(|handles| handles.eoe_port.clone())
    };
    match args.eoe_slave {
        Some(position) => port_at(position)
            .map(|port| Some((position, port)))
            .ok_or_else(|| {
                Failure::Topology(format!(
                    "--eoe-slave {position}: no EoE slave at that position"
                ))
            }),
        None => (0..built.slaves.len())
            .find_map(|position| port_at(position).map(|port| Some((position, port))))
            .ok_or_else(|| Failure::Topology("--eoe-tap: the topology has no EoE slave".into())),
    }
}

/// The master's backup port: its link and the wait on both sockets.
struct Backup {
    link: FaultInjector<RawSocket>,
    waiter: PollFds,
}

fn announce_and_serve(
    link: &mut impl Link,
    backup: Option<Backup>,
    args: &Args,
    topology: &Topology,
    built: Built,
    stop: Arc<AtomicBool>,
) -> Result<FrameCounter, Failure> {
    let Built {
        mut segment,
        time,
        slaves,
    } = built;
    // The backup port makes the ring; without one, a ring's last cable would lead nowhere
    // and its frames would be lost, so the segment stays a line.
    segment.set_ring(backup.is_some());
    let mut out = io::stdout().lock();
    let announce = |out: &mut io::StdoutLock<'_>| -> io::Result<()> {
        writeln!(out, "ecat-sim: {} slaves", topology.slaves.len())?;
        match &args.backup_iface {
            Some(name) => writeln!(
                out,
                "  ring: {} (primary) through every slave back to {name} (backup)",
                args.iface
            )?,
            None if topology.ring => writeln!(
                out,
                "  the topology is a ring but there is no --backup-iface: wired as a line"
            )?,
            None => {}
        }
        for line in slave_lines(topology, &segment) {
            writeln!(out, "  {line}")?;
        }
        if let Some(name) = &args.eoe_tap {
            let position = (0..slaves.len()).find(|&p| {
                slaves[p]
                    .eoe_port
                    .as_ref()
                    .is_some_and(HostPort::is_attached)
            });
            if let Some(position) = position {
                writeln!(out, "  EoE of slave {position} bridged to TAP {name}")?;
            }
        }
        match &args.backup_iface {
            Some(name) => writeln!(out, "ecat-sim: ready on {}, backup {name}", args.iface)?,
            None => writeln!(out, "ecat-sim: ready on {}", args.iface)?,
        }
        out.flush()
    };
    announce(&mut out).map_err(|err| Failure::Io(format!("cannot write to stdout: {err}")))?;
    drop(out);
    let changes = Arc::new(Changes::default());
    if args.control {
        let wiring = Wiring {
            slaves: segment.len(),
            ring: segment.is_ring(),
        };
        frontend::control::start(slaves, wiring, Arc::clone(&stop), Arc::clone(&changes));
    }
    let mut report = io::stderr();
    match backup {
        None => serve(link, &mut segment, &time, &stop, &changes, &mut report)
            .map_err(|err| Failure::Io(format!("link {}: {err}", args.iface))),
        Some(Backup {
            link: mut backup,
            mut waiter,
        }) => serve_ring(
            link,
            &mut backup,
            &mut waiter,
            &mut segment,
            &time,
            &stop,
            &changes,
            &mut report,
        )
        .map_err(|err| {
            let backup = args.backup_iface.as_deref().unwrap_or_default();
            Failure::Io(format!("links {} and {backup}: {err}", args.iface))
        }),
    }
}
