//! pysoem (SOEM) accepts the simulator: `ecat-sim` in one network namespace, pysoem in
//! another, a veth pair between them. Every expected value comes from the simulator's
//! built-in topology (`Topology::default_segment`) and the dictionaries it builds.
//!
//! Needs root and the venv from `scripts/test` (see tests/README.md).

use ecat_tests::pysoem_session::{hex, plan, pysoem_session, u};
use master_core::wire::coe::ObjectCode;
use sim::device::coe::lock_dictionary;
use sim::topology::{Topology, build_with_handles};

#[test]
fn pysoem_finds_maps_operates_and_talks_to_every_slave() {
    let topology = Topology::default_segment();
    let plan = plan(&topology);
    let built = build_with_handles(&topology).unwrap();
    let (r, status) = pysoem_session(&[]);
    assert!(status.success(), "ecat-sim exit after SIGTERM: {status}");

    // Discovery and the SII identity.
    assert_eq!(u(&r["slave_count"]), topology.slaves.len() as u64);
    let slaves = r["slaves"].as_array().unwrap();
    for (p, spec) in topology.slaves.iter().enumerate() {
        let s = &slaves[p];
        assert_eq!(s["name"], spec.name.as_str(), "slave {p}");
        assert_eq!(u(&s["vendor"]), u64::from(spec.vendor_id), "slave {p}");
        assert_eq!(u(&s["product"]), u64::from(spec.product_code), "slave {p}");
        assert_eq!(u(&s["revision"]), u64::from(spec.revision), "slave {p}");
    }

    // Process-data sizes from the PDO assignment (read with complete access).
    let sizes = r["pd_sizes"].as_array().unwrap();
    let mut total = 0;
    assert_eq!(sizes.len(), topology.slaves.len());
    for (p, seen) in sizes.iter().enumerate() {
        let expected = built
            .segment
            .slave(p)
            .unwrap()
            .device()
            .process_data_sizes();
        assert_eq!(
            (u(&seen["outputs"]), u(&seen["inputs"])),
            (u64::from(expected.outputs), u64::from(expected.inputs)),
            "slave {p} outputs/inputs"
        );
        total += u64::from(expected.outputs) + u64::from(expected.inputs);
    }
    assert_eq!(u(&r["iomap_size"]), total);

    // SAFEOP, then OP for every slave with the cycle running, and a full working counter.
    assert_eq!(u(&r["safeop"]), 4, "SAFEOP reached");
    assert_eq!(u(&r["op"]), 8, "OP reached");
    for (p, state) in r["states"].as_array().unwrap().iter().enumerate() {
        assert_eq!(u(state), 8, "slave {p} in OP");
    }
    assert!(u(&r["expected_wkc"]) > 0);
    assert_eq!(
        u(&r["wkc"]),
        u(&r["expected_wkc"]),
        "cyclic working counter"
    );

    // SDO reads of the identity object.
    for &p in &plan.coe {
        let spec = &topology.slaves[p];
        let identity: Vec<u64> = r["identity"][p.to_string()]
            .as_array()
            .unwrap()
            .iter()
            .map(u)
            .collect();
        let expected = [
            spec.vendor_id,
            spec.product_code,
            spec.revision,
            spec.serial,
        ];
        assert_eq!(identity, expected.map(u64::from), "slave {p} 0x1018");
    }

    // The large object: its initial value, then what pysoem wrote, read back.
    let (large_slave, large_index) = plan.large;
    let dict = built.slaves[large_slave].dictionary.clone().unwrap();
    let initial = lock_dictionary(&dict)
        .get_bytes(large_index, 0)
        .unwrap()
        .to_vec();
    assert!(initial.len() >= 4096);
    assert_eq!(r["large"]["before"], hex(&initial).as_str());
    assert_eq!(r["large"]["read_back"], r["large"]["written"]);
    assert_ne!(r["large"]["written"], r["large"]["before"]);

    // The object list through SDO Information.
    for &p in &plan.coe {
        let dict = built.slaves[p].dictionary.clone().unwrap();
        let dict = lock_dictionary(&dict);
        let listed = r["od"][p.to_string()].as_array().unwrap();
        let objects: Vec<_> = dict.objects().collect();
        assert_eq!(listed.len(), objects.len(), "slave {p} object count");
        for (seen, object) in listed.iter().zip(objects) {
            assert_eq!(u(&seen["index"]), u64::from(object.index));
            assert_eq!(seen["name"], object.name.as_str(), "0x{:04X}", object.index);
            assert_eq!(
                u(&seen["object_code"]),
                u64::from(u8::from(object.object_code)),
                "0x{:04X}",
                object.index
            );
            if object.object_code != ObjectCode::Var {
                assert_eq!(
                    u(&seen["entries"]),
                    object.entries.len() as u64,
                    "0x{:04X} entries",
                    object.index
                );
            }
        }
    }

    // FoE write then read.
    assert_eq!(r["foe"]["read_back"], r["foe"]["written"]);
    assert!(!r["foe"]["written"].as_str().unwrap().is_empty());
}
