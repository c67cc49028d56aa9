//! Issue 23, item 3: the gateway with several receive workers (one UDP socket each on the
//! shared port, `GatewayConfig::workers`) keeps what one worker guaranteed: one client's
//! requests run in the order sent, a repeated request runs once whichever worker sees it,
//! and a client's segmented transfer holds its slave against clients served by other
//! workers. Many clients (their own sockets, so the kernel spreads them over the workers)
//! run at once in each test.
//!
//! The same guarantees hold with the bus thread serving UDP (`GatewayConfig::on_bus_thread`,
//! the default, where requests from every client run as tasks on one thread): the ordering,
//! repeat and session tests run both ways.

use crate::gateway_support;

use std::sync::Barrier;
use std::time::{Duration, Instant};

use gateway_support::{
    COE_STORE, Client, DRIVE, GwRig, PATIENCE, datagram, one_download_against_uploads, sdo,
    station, test_config,
};
use master_core::gateway::GatewayConfig;
use master_core::wire::coe::{SdoPayload, SdoRequest, SdoResponse};
use master_core::wire::mailbox::MailboxType;

const WORKERS: usize = 4;
const CLIENTS: usize = 16;
/// The CoE store's parameter: a writable u32 no process data touches, whose writes the
/// simulated slave counts.
const PARAMETER: u16 = 0x2001;

/// Who serves UDP in a test.
#[derive(Clone, Copy)]
enum Served {
    ByWorkers,
    ByTheBusThread,
}

fn config(served: Served) -> GatewayConfig {
    GatewayConfig {
        workers: WORKERS,
        retry_window: Duration::from_secs(30),
        on_bus_thread: matches!(served, Served::ByTheBusThread),
        ..test_config()
    }
}

fn download(value: u32) -> Vec<u8> {
    sdo(SdoRequest::InitiateDownload {
        index: PARAMETER,
        subindex: 0,
        complete_access: false,
        payload: SdoPayload::Expedited(&value.to_le_bytes()),
    })
}

fn writes(rig: &GwRig) -> u32 {
    rig.handles[COE_STORE]
        .dictionary
        .as_ref()
        .expect("CoE")
        .lock()
        .unwrap()
        .write_count(PARAMETER)
}

fn parameter(rig: &GwRig) -> u32 {
    let dict = rig.handles[COE_STORE].dictionary.as_ref().expect("CoE");
    let bytes = dict
        .lock()
        .unwrap()
        .get_bytes(PARAMETER, 0)
        .unwrap()
        .to_vec();
    u32::from_le_bytes(bytes.try_into().expect("a u32"))
}

/// Names of this process's threads.
fn thread_names() -> Vec<String> {
    std::fs::read_dir("/proc/self/task")
        .expect("/proc/self/task")
        .filter_map(|t| std::fs::read_to_string(t.ok()?.path().join("comm")).ok())
        .map(|name| name.trim_end().to_owned())
        .collect()
}

/// Waits until `want` gateway worker threads run (a new thread names itself once it
/// runs); the names seen last if that does not happen within `PATIENCE`.
fn expect_workers(want: usize) {
    let deadline = Instant::now() + PATIENCE;
    loop {
        let names = thread_names();
        let workers = names
            .iter()
            .filter(|n| n.starts_with("ecat-gateway-"))
            .count();
        if workers == want {
            return;
        }
        assert!(Instant::now() < deadline, "want {want} workers: {names:?}");
        std::thread::yield_now();
    }
}

#[test]
fn every_worker_has_its_thread_and_all_of_them_stop() {
    let mut rig = GwRig::start(config(Served::ByWorkers));
    expect_workers(WORKERS);
    // Every client is answered, whichever worker the kernel gave it to.
    for _ in 0..CLIENTS {
        let mut client = rig.client();
        assert_eq!(
            client.upload(station(DRIVE), 0x1018, 1).expect("upload"),
            sim::topology::SIM_VENDOR_ID.to_le_bytes()
        );
    }
    rig.gateway_mut().stop();
    // Joined; the kernel may list an exited thread a moment longer.
    expect_workers(0);
    let addr = rig.gateway_mut().start().expect("restart");
    expect_workers(WORKERS);
    let mut client = Client::new(addr);
    assert!(client.upload(station(DRIVE), 0x1018, 1).is_ok());
}

/// On the bus thread: one worker is left (TCP, timers), the requests are answered, and a
/// stop gives the port up before it returns, so that it can be bound again at once.
#[test]
fn the_bus_thread_serves_udp_and_a_stop_gives_the_port_up_at_once() {
    let mut rig = GwRig::start(config(Served::ByTheBusThread));
    assert!(
        rig.gateway().on_bus_thread(),
        "the in-process link can be waited on"
    );
    expect_workers(1);
    for _ in 0..CLIENTS {
        let mut client = rig.client();
        assert_eq!(
            client.upload(station(DRIVE), 0x1018, 1).expect("upload"),
            sim::topology::SIM_VENDOR_ID.to_le_bytes()
        );
    }
    let addr = rig.gateway().local_addr().expect("running");
    for _ in 0..3 {
        rig.gateway_mut().stop();
        assert!(!rig.gateway().on_bus_thread());
        // A plain socket binds the port at once: the bus thread no longer holds it.
        drop(std::net::UdpSocket::bind(addr).expect("the port is free after the stop"));
        rig.gateway_mut().set_port(addr.port());
        assert_eq!(rig.gateway_mut().start().expect("restart"), addr);
        let mut client = Client::new(addr);
        assert!(client.upload(station(DRIVE), 0x1018, 1).is_ok());
    }
}

#[test]
fn one_clients_pipelined_writes_run_in_the_order_sent() {
    pipelined_writes_run_in_the_order_sent(Served::ByWorkers);
}

#[test]
fn one_clients_pipelined_writes_run_in_the_order_sent_on_the_bus_thread() {
    pipelined_writes_run_in_the_order_sent(Served::ByTheBusThread);
}

fn pipelined_writes_run_in_the_order_sent(served: Served) {
    let rig = GwRig::start(config(served));
    let before = writes(&rig);
    let each: u32 = 12;
    for c in 0..CLIENTS as u32 {
        let mut client = rig.client();
        // All sent before the first reply is read: only the gateway keeps them in order.
        let values: Vec<u32> = (1..=each).map(|i| c * 100 + i).collect();
        for &value in &values {
            client.send(station(COE_STORE), MailboxType::Coe, &download(value));
        }
        for _ in &values {
            let reply = client.recv();
            assert!(
                matches!(reply.sdo(), SdoResponse::InitiateDownload { .. }),
                "{reply:?}"
            );
        }
        assert_eq!(parameter(&rig), c * 100 + each, "the last write stays");
    }
    assert_eq!(
        writes(&rig),
        before + each * CLIENTS as u32,
        "every write ran once"
    );
}

#[test]
fn repeats_run_once_with_many_clients_on_many_workers() {
    repeats_run_once_with_many_clients(Served::ByWorkers);
}

#[test]
fn repeats_run_once_with_many_clients_on_the_bus_thread() {
    repeats_run_once_with_many_clients(Served::ByTheBusThread);
}

fn repeats_run_once_with_many_clients(served: Served) {
    let rig = GwRig::start(config(served));
    let before = writes(&rig);
    let start = Barrier::new(CLIENTS);
    std::thread::scope(|s| {
        for c in 0..CLIENTS as u32 {
            let (rig, start) = (&rig, &start);
            s.spawn(move || {
                let client = rig.client();
                let message = datagram(station(COE_STORE), MailboxType::Coe, 5, &download(c));
                start.wait();
                client.send_raw(&message);
                let first = client.recv();
                for _ in 0..3 {
                    client.send_raw(&message);
                    assert_eq!(client.recv().data, first.data, "the stored reply");
                }
            });
        }
    });
    assert_eq!(
        writes(&rig),
        before + CLIENTS as u32,
        "each download ran once"
    );
    let stats = rig.gateway().stats();
    assert_eq!(stats.retries_answered, 3 * CLIENTS as u64);
    assert_eq!(stats.failed_requests, 0, "{stats:?}");
}

#[test]
fn a_segmented_transfer_holds_its_slave_against_clients_of_other_workers() {
    a_transfer_holds_its_slave_against_other_clients(Served::ByWorkers);
}

#[test]
fn a_segmented_transfer_holds_its_slave_against_other_clients_on_the_bus_thread() {
    a_transfer_holds_its_slave_against_other_clients(Served::ByTheBusThread);
}

fn a_transfer_holds_its_slave_against_other_clients(served: Served) {
    let rig = GwRig::start(config(served));
    let new: Vec<u8> = (0..4096u32).map(|i| (i % 11) as u8 ^ 0xA5).collect();
    one_download_against_uploads(&rig, &new, CLIENTS - 1, 2);
    let stats = rig.gateway().stats();
    assert_eq!(stats.failed_requests, 0, "{stats:?}");
}
