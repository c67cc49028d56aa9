//! The raw socket on a real (virtual) Ethernet: a veth pair `a` <-> `b` in a network
//! namespace of the test's own, so the host's interfaces are never touched.
//!
//! Needs root and iproute2's `ip`; fails with a message saying so otherwise.

use crate::bus_support;

use std::io;
use std::time::{Duration, Instant};

use bus_support::frames::{MIN_FRAME_LEN, seq_of, test_frame};
use bus_support::netns::NetNs;
use master_core::link::{Link, MAX_FRAME_LEN, RawSocket, RawSocketOptions, Wait};

/// Far longer than a frame needs to cross a veth pair; only reached if something is broken.
const PATIENCE: Duration = Duration::from_secs(5);

/// Long enough for a frame that is on its way to have arrived: used to show one is not.
const QUIET: Duration = Duration::from_millis(50);

fn soon() -> Wait {
    Wait::Until(Instant::now() + PATIENCE)
}

/// A namespace with a veth pair `a` <-> `b`, both up.
fn veth_pair() -> NetNs {
    let ns = NetNs::new();
    ns.add_veth_pair("a", "b");
    ns
}

/// Sends frames both ways between sockets on `a` and `b` and checks that they arrive intact
/// and that neither end reads back its own frame.
fn frames_cross_both_ways(options: RawSocketOptions) {
    let ns = veth_pair();
    ns.run_inside(|| {
        let mut a = RawSocket::open("a", options).unwrap();
        let mut b = RawSocket::open("b", options).unwrap();
        let mut buf = [0u8; MAX_FRAME_LEN];

        for (seq, len) in [(1, MIN_FRAME_LEN), (2, 300), (3, 1514)] {
            let frame = test_frame(seq, len);
            a.send(&frame).unwrap();
            let got = b.recv(&mut buf, soon()).unwrap().expect("frame a -> b");
            assert_eq!(&buf[..got], &frame[..], "a -> b, frame {seq}");

            let reply = test_frame(seq + 100, len);
            b.send(&reply).unwrap();
            let got = a.recv(&mut buf, soon()).unwrap().expect("frame b -> a");
            assert_eq!(&buf[..got], &reply[..], "b -> a, frame {seq}");
        }

        // Each end has now sent three frames and read three; none of its own came back.
        let quiet = Wait::Until(Instant::now() + QUIET);
        assert_eq!(
            a.recv(&mut buf, quiet).unwrap(),
            None,
            "a read back its own frame"
        );
        assert_eq!(
            b.recv(&mut buf, Wait::NoWait).unwrap(),
            None,
            "b read back its own frame"
        );
    });
}

#[test]
fn link_raw_socket_frames_cross_veth_both_ways_in_poll_mode() {
    frames_cross_both_ways(RawSocketOptions::default());
}

#[test]
fn link_raw_socket_frames_cross_veth_both_ways_in_busy_poll_mode_with_qdisc_bypass() {
    frames_cross_both_ways(RawSocketOptions {
        busy_poll: true,
        qdisc_bypass: true,
        ..RawSocketOptions::default()
    });
}

#[test]
fn link_raw_socket_frames_cross_veth_both_ways_with_a_spin_window() {
    frames_cross_both_ways(RawSocketOptions {
        spin: Duration::from_micros(200),
        ..RawSocketOptions::default()
    });
}

/// CPU time the calling thread has used.
fn thread_cpu_time() -> Duration {
    let mut now = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `now` is a valid, writable timespec for the call's duration.
    let result = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut now) };
    assert_eq!(result, 0, "clock_gettime: {}", io::Error::last_os_error());
    Duration::new(now.tv_sec as u64, now.tv_nsec as u32)
}

#[test]
fn link_raw_socket_spin_window_ends_in_a_sleep_and_never_outlasts_the_deadline() {
    let ns = veth_pair();
    ns.run_inside(|| {
        let mut buf = [0u8; MAX_FRAME_LEN];
        // A window shorter than the wait: spins 1 ms, then sleeps until the deadline, so
        // the thread uses far less CPU than the wait lasts (a busy poll would use it all).
        let wait = Duration::from_millis(200);
        let mut a = RawSocket::open(
            "a",
            RawSocketOptions {
                spin: Duration::from_millis(1),
                ..RawSocketOptions::default()
            },
        )
        .unwrap();
        let cpu = thread_cpu_time();
        let deadline = Instant::now() + wait;
        assert_eq!(a.recv(&mut buf, Wait::Until(deadline)).unwrap(), None);
        assert!(Instant::now() >= deadline, "gave up early");
        let used = thread_cpu_time() - cpu;
        assert!(
            used < wait / 2,
            "spun through the whole wait: {used:?} of CPU"
        );

        // A window longer than the wait: the deadline still ends it.
        let mut b = RawSocket::open(
            "b",
            RawSocketOptions {
                spin: Duration::from_secs(60),
                ..RawSocketOptions::default()
            },
        )
        .unwrap();
        let deadline = Instant::now() + QUIET;
        assert_eq!(b.recv(&mut buf, Wait::Until(deadline)).unwrap(), None);
        let now = Instant::now();
        assert!(now >= deadline, "gave up early");
        assert!(now < deadline + PATIENCE, "spun past the deadline");
        // And a frame that arrives during the window is taken.
        a.send(&test_frame(9, MIN_FRAME_LEN)).unwrap();
        let len = b.recv(&mut buf, soon()).unwrap().expect("the frame");
        assert_eq!(seq_of(&buf[..len]), 9);
    });
}

#[test]
fn link_raw_socket_sender_does_not_read_back_its_own_frame() {
    let ns = veth_pair();
    ns.run_inside(|| {
        let mut a = RawSocket::open("a", RawSocketOptions::default()).unwrap();
        let mut b = RawSocket::open("b", RawSocketOptions::default()).unwrap();
        let mut buf = [0u8; MAX_FRAME_LEN];
        let frame = test_frame(5, MIN_FRAME_LEN);
        a.send(&frame).unwrap();
        // Once b has the frame, a copy for a would have been queued already.
        assert!(b.recv(&mut buf, soon()).unwrap().is_some());
        let quiet = Wait::Until(Instant::now() + QUIET);
        assert_eq!(a.recv(&mut buf, quiet).unwrap(), None);
    });
}

#[test]
fn link_raw_socket_recv_times_out_with_none_when_nothing_is_sent() {
    let ns = veth_pair();
    ns.run_inside(|| {
        for options in [
            RawSocketOptions::default(),
            RawSocketOptions {
                busy_poll: true,
                ..RawSocketOptions::default()
            },
        ] {
            let mut a = RawSocket::open("a", options).unwrap();
            let mut buf = [0u8; MAX_FRAME_LEN];
            assert_eq!(a.recv(&mut buf, Wait::NoWait).unwrap(), None);

            let deadline = Instant::now() + QUIET;
            assert_eq!(a.recv(&mut buf, Wait::Until(deadline)).unwrap(), None);
            let now = Instant::now();
            assert!(now >= deadline, "gave up early ({options:?})");
            assert!(now < deadline + PATIENCE, "overslept ({options:?})");
        }
    });
}

#[test]
fn link_raw_socket_receives_only_ethercat_but_from_any_source_mac() {
    let ns = veth_pair();
    ns.run_inside(|| {
        let mut a = RawSocket::open("a", RawSocketOptions::default()).unwrap();
        let mut b = RawSocket::open("b", RawSocketOptions::default()).unwrap();
        let mut buf = [0u8; MAX_FRAME_LEN];

        // Another EtherType on the same wire is not ours.
        let mut ipv4 = test_frame(1, MIN_FRAME_LEN);
        ipv4[12..14].copy_from_slice(&[0x08, 0x00]);
        a.send(&ipv4).unwrap();
        // A slave may flip the locally-administered bit of the source MAC: still ours.
        let mut flipped = test_frame(2, MIN_FRAME_LEN);
        flipped[6] ^= 0x02;
        a.send(&flipped).unwrap();

        let got = b
            .recv(&mut buf, soon())
            .unwrap()
            .expect("the EtherCAT frame");
        assert_eq!(seq_of(&buf[..got]), 2, "the IPv4 frame came through");
        assert_eq!(&buf[..got], &flipped[..]);
    });
}

#[test]
fn link_raw_socket_reports_the_interface_mac_address_and_mtu() {
    let ns = veth_pair();
    ns.ip(&["link", "set", "dev", "a", "address", "02:00:5e:00:88:a4"]);
    ns.ip(&["link", "set", "dev", "a", "mtu", "1400"]);
    ns.run_inside(|| {
        let a = RawSocket::open("a", RawSocketOptions::default()).unwrap();
        assert_eq!(a.mac_address(), [0x02, 0x00, 0x5e, 0x00, 0x88, 0xa4]);
        assert_eq!(a.mtu(), 1400);
        assert_eq!(a.interface(), "a");
        assert!(a.interface_index() > 0);
    });
}

#[test]
fn link_raw_socket_open_names_a_missing_interface() {
    let ns = NetNs::new();
    ns.run_inside(|| {
        let err = RawSocket::open("ecat-missing0", RawSocketOptions::default()).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::NotFound);
        assert!(err.to_string().contains("ecat-missing0"), "{err}");
    });
}

#[test]
fn link_raw_socket_open_refuses_a_non_ethernet_interface() {
    let ns = NetNs::new();
    ns.run_inside(|| {
        let err = RawSocket::open("lo", RawSocketOptions::default()).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        assert!(err.to_string().contains("not Ethernet"), "{err}");
    });
}

#[test]
fn link_raw_socket_open_refuses_an_impossible_interface_name() {
    for name in ["", "name-longer-than-15", "a/b", "a b"] {
        let err = RawSocket::open(name, RawSocketOptions::default()).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput, "{name:?}");
    }
}

#[test]
fn link_raw_socket_keeps_its_namespace_on_another_thread() {
    let ns = veth_pair();
    let (mut a, mut b) = ns.run_inside(|| {
        (
            RawSocket::open("a", RawSocketOptions::default()).unwrap(),
            RawSocket::open("b", RawSocketOptions::default()).unwrap(),
        )
    });
    // This thread is still in the host's namespace; the sockets are not.
    let frame = test_frame(8, MIN_FRAME_LEN);
    a.send(&frame).unwrap();
    let mut buf = [0u8; MAX_FRAME_LEN];
    let got = b.recv(&mut buf, soon()).unwrap().expect("frame a -> b");
    assert_eq!(&buf[..got], &frame[..]);
}

#[test]
fn link_raw_socket_netns_guard_deletes_its_namespace_even_after_a_panic() {
    let ns = veth_pair();
    let path = ns.path();
    assert!(path.exists());
    let outcome = std::panic::catch_unwind(move || {
        let _ns = ns;
        panic!("a failing test body");
    });
    assert!(outcome.is_err());
    assert!(!path.exists(), "{} survived", path.display());
}

#[test]
fn link_raw_socket_open_without_cap_net_raw_says_what_is_missing() {
    let outcome = std::thread::spawn(|| {
        const NOBODY: libc::uid_t = 65534;
        // SAFETY: the raw system call (unlike glibc's wrapper, which changes every thread)
        // gives up root and with it all capabilities on this thread only; the thread does
        // nothing else that needs them and ends right after.
        let result = unsafe { libc::syscall(libc::SYS_setresuid, NOBODY, NOBODY, NOBODY) };
        assert_eq!(result, 0, "setresuid: {}", io::Error::last_os_error());
        RawSocket::open("lo", RawSocketOptions::default()).unwrap_err()
    })
    .join()
    .unwrap();
    assert_eq!(outcome.kind(), io::ErrorKind::PermissionDenied);
    assert!(outcome.to_string().contains("CAP_NET_RAW"), "{outcome}");
}
