//! The repeat procedure (spec-notes §mbx.repeat): getting back a message whose read was lost.
//!
//! Reading SM1 empties it, so when the frame carrying the read does not come back, the
//! message it read is gone — unless the master toggles the repeat request bit (SM1 activate
//! byte 0x080E, bit 1) and the slave re-posts its last message, acknowledging in 0x080F
//! bit 1. The frame may also have been lost before it reached the slave; the slave then
//! re-posts a message the master already has, which the slave's counter reveals
//! ([`super::counter::Counters::accept_rx`]).

use std::time::{Duration, Instant};

use crate::bus::{BusError, BusHandle, DatagramResponse};
use crate::mailbox::error::{MailboxError, Result};
use crate::wire::register::sync_manager::{SmActivate, SmPdiControl};

use super::timer::Timer;

/// SM1 status (0x080D) and activate (0x080E).
const SM1_STATUS: u16 = 0x080D;
/// SM1 activate: bit 1 is the repeat request.
const SM1_ACTIVATE: u16 = 0x080E;
/// SM1 PDI control: bit 1 is the repeat acknowledge.
const SM1_PDI_CONTROL: u16 = 0x080F;

/// Toggles the repeat request of slave `station` and waits until the slave acknowledges
/// it (or `deadline`, checking every `interval` on the engine's `timer`).
pub(crate) async fn request_repeat(
    bus: &BusHandle,
    station: u16,
    deadline: Instant,
    interval: Duration,
    timer: &Timer,
) -> Result<()> {
    let registers = checked(bus.fprd(station, SM1_STATUS, 2).await)?;
    let raw = registers.get(1).copied().unwrap_or(0);
    let mut activate = SmActivate::decode(raw);
    activate.repeat_request = !activate.repeat_request;
    // An absolute value, so a bus retry of this write cannot toggle twice.
    checked(bus.fpwr(station, SM1_ACTIVATE, [activate.encode()]).await)?;
    loop {
        let pdi = checked(bus.fprd(station, SM1_PDI_CONTROL, 1).await)?;
        let ack = SmPdiControl::decode(pdi.first().copied().unwrap_or(0)).repeat_ack;
        if ack == activate.repeat_request {
            return Ok(());
        }
        if Instant::now() >= deadline {
            return Err(MailboxError::Timeout {
                station,
                waiting_for: "the repeat acknowledge",
            });
        }
        timer.sleep(interval).await;
    }
}

/// The data of a register access that the slave answered (working counter 1).
///
/// Any other working counter means no slave with this station address processed the
/// access: the slave is gone from the segment (power, cable) or was renumbered. That is
/// the bus's fault to report, not a protocol violation by the slave.
fn checked(result: core::result::Result<DatagramResponse, BusError>) -> Result<Vec<u8>> {
    let response = result?;
    if response.wkc != 1 {
        return Err(MailboxError::Bus(BusError::WorkingCounter {
            expected: 1,
            got: response.wkc,
            response,
        }));
    }
    Ok(response.data.to_vec())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::DatagramData;
    use crate::wire::command::DatagramAddress;

    fn answer(wkc: u16) -> core::result::Result<DatagramResponse, BusError> {
        Ok(DatagramResponse {
            data: DatagramData::from_slice(&[0x08, 0x01]),
            wkc,
            address: DatagramAddress::Node {
                station: 0x03E9,
                ado: SM1_STATUS,
            },
            irq: 0,
            sent_at: crate::bus::Stamp::from_instant(std::time::Instant::now()),
            polled_us: 0,
        })
    }

    #[test]
    fn an_access_no_slave_answered_is_a_bus_fault_not_a_protocol_violation() {
        assert_eq!(checked(answer(1)).expect("answered"), [0x08, 0x01]);
        let err = checked(answer(0)).expect_err("nobody answered");
        assert!(
            matches!(
                err,
                MailboxError::Bus(BusError::WorkingCounter {
                    expected: 1,
                    got: 0,
                    ..
                })
            ),
            "{err:?}"
        );
        assert_eq!(err.to_string(), "bus: working counter 0, expected 1");
    }
}
