//! `--control`: the simulated terminals' physical side, reachable from outside the process.
//!
//! A test on the veth rig cannot hold the handles an in-process test uses, so `ecat-sim
//! --control` offers them over its standard streams:
//! - stdout: `ecat-sim: outputs <position> <hex>` each time a digital output terminal's
//!   physical outputs change (and once for each at start), as the in-process
//!   `OutputProbe` would show them;
//! - stdin, one command a line: `input <position> <channel> <0|1>` sets a digital input
//!   (on a terminal wired to outputs, `wired_to`, in parallel with the wire: 0 leaves an
//!   input on while its output is on),
//!   `emergency <position> <code hex> [<error register hex> <5 data bytes hex>]` raises a
//!   CoE emergency on a slave (without the last two: error register 0, zero bytes),
//!   `power-cycle <position>` power-cycles a slave before the next frame. Cable redundancy
//!   (ETG.1000.3 §4.2), also made before the next frame: `break <cable>` cuts a cable
//!   (`break 0` the master's primary cable, `break k` the cable after k slaves, `break n`
//!   with n slaves the cable back to the master's backup port, ring only), `kill
//!   <position>` takes a slave's power (it neither processes nor forwards; its neighbours
//!   lose their links to it), `heal` reconnects every cable and powers every slave (a
//!   killed slave comes back in INIT, as after a power cycle). Each command is answered
//!   `ecat-sim: ok <command>` or `ecat-sim: error <reason>` on stdout.
//!
//! Both run on threads of their own, touching only the shared handles and the queue of
//! segment changes ([`super::changes`]), never the frame loop.

use std::io::{self, BufRead, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::Duration;

use sim::topology::SlaveHandles;

use super::changes::{Change, Changes};

/// How often the output reporter looks at the terminals.
const OUTPUT_POLL: Duration = Duration::from_millis(1);

/// What the command reader knows of the segment to check its commands against.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Wiring {
    /// Number of slaves.
    pub slaves: usize,
    /// Whether the last slave is wired back to the master's backup port.
    pub ring: bool,
}

/// Starts the output reporter and the command reader; both end with `stop` (the reader
/// also when stdin closes). Segment changes go to `changes` for the frame loop.
pub fn start(
    handles: Vec<SlaveHandles>,
    wiring: Wiring,
    stop: Arc<AtomicBool>,
    changes: Arc<Changes>,
) {
    let probes: Vec<_> = handles
        .iter()
        .enumerate()
        .filter_map(|(position, h)| h.outputs.clone().map(|probe| (position, probe)))
        .collect();
    let reporter_stop = Arc::clone(&stop);
    thread::spawn(move || {
        let mut last: Vec<Option<Vec<u8>>> = vec![None; probes.len()];
        while !reporter_stop.load(Ordering::Relaxed) {
            for ((position, probe), last) in probes.iter().zip(&mut last) {
                let image = probe.image();
                if last.as_ref() != Some(&image) {
                    say(&format!("outputs {position} {}", hex(&image)));
                    *last = Some(image);
                }
            }
            thread::sleep(OUTPUT_POLL);
        }
    });
    thread::spawn(move || {
        for line in io::stdin().lock().lines() {
            let Ok(line) = line else { break };
            if stop.load(Ordering::Relaxed) {
                break;
            }
            match command(&handles, wiring, &changes, &line) {
                Ok(()) => say(&format!("ok {}", line.trim())),
                Err(reason) => say(&format!("error {reason}")),
            }
        }
    });
}

fn say(line: &str) {
    let mut out = io::stdout().lock();
    // A closed stdout must not stop the simulator.
    let _ = writeln!(out, "ecat-sim: {line}").and_then(|()| out.flush());
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// A decimal number.
fn number(word: &str, what: &str) -> Result<usize, String> {
    word.parse().map_err(|_| format!("bad {what} {word:?}"))
}

/// Five bytes written as ten hex digits.
fn five_bytes(word: &str) -> Result<[u8; 5], String> {
    let digits = word.trim_start_matches("0x");
    let bad = || format!("bad data {word:?}: five bytes in hex");
    if digits.len() != 10 || !digits.is_ascii() {
        return Err(bad());
    }
    let mut bytes = [0u8; 5];
    for (i, byte) in bytes.iter_mut().enumerate() {
        let pair = digits.get(2 * i..2 * i + 2).ok_or_else(bad)?;
        *byte = u8::from_str_radix(pair, 16).map_err(|_| bad())?;
    }
    Ok(bytes)
}

/// Carries out one command line.
fn command(
    handles: &[SlaveHandles],
    wiring: Wiring,
    changes: &Changes,
    line: &str,
) -> Result<(), String> {
    let words: Vec<&str> = line.split_whitespace().collect();
    let slave = |word: &str| -> Result<&SlaveHandles, String> {
        let position: usize = word.parse().map_err(|_| format!("bad position {word:?}"))?;
        handles
            .get(position)
            .ok_or_else(|| format!("no slave at position {position}"))
    };
    match words.as_slice() {
        ["input", position, channel, value] => {
            let driver = slave(position)?
                .inputs
                .as_ref()
                .ok_or("not a digital input terminal")?;
            let channel: u16 = channel
                .parse()
                .map_err(|_| format!("bad channel {channel:?}"))?;
            let on = match *value {
                "0" => false,
                "1" => true,
                other => return Err(format!("bad value {other:?}")),
            };
            driver.set_input(channel, on);
            Ok(())
        }
        ["emergency", position, code, rest @ ..] => {
            let trigger = slave(position)?
                .emergencies
                .as_ref()
                .ok_or("not a CoE slave")?;
            let hex_u16 = |word: &str, what: &str| {
                u16::from_str_radix(word.trim_start_matches("0x"), 16)
                    .map_err(|_| format!("bad {what} {word:?}"))
            };
            let code = hex_u16(code, "code")?;
            let (register, data) = match rest {
                [] => (0, [0; 5]),
                [register, data] => {
                    let register = u8::try_from(hex_u16(register, "error register")?)
                        .map_err(|_| format!("bad error register {register:?}"))?;
                    (register, five_bytes(data)?)
                }
                _ => return Err(format!("unknown command {line:?}")),
            };
            if trigger.raise(code, register, data) {
                Ok(())
            } else {
                Err("emergency queue full".into())
            }
        }
        ["power-cycle", position] => {
            slave(position)?;
            changes.request(Change::PowerCycle(number(position, "position")?));
            Ok(())
        }
        ["kill", position] => {
            slave(position)?;
            changes.request(Change::Kill(number(position, "position")?));
            Ok(())
        }
        ["break", cable] => {
            let cable = number(cable, "cable")?;
            // Cable n (after the last slave) goes back to the backup port: a ring's only.
            let last = if wiring.ring {
                wiring.slaves
            } else {
                wiring.slaves.saturating_sub(1)
            };
            if cable > last {
                let wired = if wiring.ring { "ring" } else { "line" };
                return Err(format!(
                    "no cable {cable}: cables 0 to {last} in this {wired} of {} slaves",
                    wiring.slaves
                ));
            }
            changes.request(Change::Break(cable));
            Ok(())
        }
        ["heal"] => {
            changes.request(Change::Heal);
            Ok(())
        }
        _ => Err(format!("unknown command {line:?}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sim::topology::{Topology, build_with_handles};

    #[test]
    fn commands_reach_the_handles_and_bad_ones_are_refused() {
        let built = build_with_handles(&Topology::default_segment()).unwrap();
        let handles = built.slaves;
        let changes = Changes::default();
        let wiring = Wiring {
            slaves: handles.len(),
            ring: false,
        };
        let command = |line: &str| command(&handles, wiring, &changes, line);
        command("input 2 5 1").unwrap();
        assert!(command("input 1 5 1").is_err(), "DO8 has no inputs");
        command("emergency 3 0x8100").unwrap();
        command("emergency 3 8130 11 deadbeef01").unwrap();
        assert_eq!(handles[3].emergencies.as_ref().unwrap().pending(), 2);
        assert!(command("emergency 3 8130 11 dead").is_err());
        assert!(command("emergency 3 8130 1ff deadbeef01").is_err());
        assert!(command("emergency 9 8100").is_err());
        assert!(command("input 2 x 1").is_err());
        assert!(command("reboot").is_err());
        command("power-cycle 1").unwrap();
        assert!(command("power-cycle 9").is_err());
        assert_eq!(changes.queued(), vec![Change::PowerCycle(1)]);
    }

    #[test]
    fn cable_and_power_commands_are_checked_against_the_wiring_and_queued() {
        let built = build_with_handles(&Topology::default_segment()).unwrap();
        let handles = built.slaves;
        let n = handles.len();
        let changes = Changes::default();
        let ring = Wiring {
            slaves: n,
            ring: true,
        };
        let line = Wiring {
            ring: false,
            ..ring
        };
        command(&handles, ring, &changes, "break 0").unwrap();
        command(&handles, ring, &changes, "break 2").unwrap();
        command(&handles, ring, &changes, &format!("break {n}")).unwrap();
        let err = command(&handles, line, &changes, &format!("break {n}")).unwrap_err();
        assert!(err.contains("line"), "{err}");
        assert!(command(&handles, ring, &changes, &format!("break {}", n + 1)).is_err());
        assert!(command(&handles, ring, &changes, "break -1").is_err());
        assert!(command(&handles, ring, &changes, "break").is_err());
        command(&handles, ring, &changes, "kill 4").unwrap();
        assert!(command(&handles, ring, &changes, &format!("kill {n}")).is_err());
        assert!(command(&handles, ring, &changes, "kill x").is_err());
        command(&handles, ring, &changes, " heal ").unwrap();
        assert!(command(&handles, ring, &changes, "heal 1").is_err());
        assert_eq!(
            changes.queued(),
            vec![
                Change::Break(0),
                Change::Break(2),
                Change::Break(n),
                Change::Kill(4),
                Change::Heal
            ]
        );
    }
}
