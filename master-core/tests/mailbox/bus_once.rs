//! `BusHandle::submit_once`: a datagram whose frame is lost fails instead of being sent
//! again (the mailbox layer reads SM1 this way and recovers with the repeat procedure).

use std::time::Duration;

use master_core::bus::{Bus, BusConfig, BusError};
use master_core::link::{FaultConfig, FaultInjector};
use sim::link::InProcessLink;
use sim::topology::{Topology, build};

fn config() -> BusConfig {
    BusConfig {
        response_timeout: Duration::from_millis(2),
        retries: 3,
        ..BusConfig::default()
    }
}

#[test]
fn a_lost_send_once_datagram_is_not_sent_again() {
    let segment = build(&Topology::default_segment()).unwrap();
    let lossy = FaultConfig {
        drop_tx: 1.0,
        ..FaultConfig::default()
    };
    let link = FaultInjector::new(InProcessLink::new(segment), lossy, 1);
    let (bus, thread) = Bus::start(link, config()).unwrap();
    let once = bus
        .submit_once(master_core::bus::DatagramRequest::brd(0x0000, 2))
        .wait();
    assert_eq!(once.unwrap_err(), BusError::Timeout { attempts: 1 });
    assert_eq!(bus.stats().retries, 0, "nothing was sent again");
    let retried = bus.brd(0x0000, 2).wait();
    assert_eq!(retried.unwrap_err(), BusError::Timeout { attempts: 4 });
    assert_eq!(bus.stats().retries, 3);
    drop(bus);
    let link = thread.join().unwrap();
    assert_eq!(link.counts().tx_dropped, 5, "one try, then four");
}

#[test]
fn a_send_once_datagram_that_comes_back_completes_normally() {
    let segment = build(&Topology::default_segment()).unwrap();
    let (bus, thread) = Bus::start(InProcessLink::new(segment), config()).unwrap();
    let reply = bus
        .submit_once(master_core::bus::DatagramRequest::brd(0x0000, 2))
        .wait()
        .unwrap();
    assert_eq!(reply.wkc, 5, "the five slaves of the default segment");
    drop(bus);
    drop(thread.join());
}
