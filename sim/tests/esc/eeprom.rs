//! The SII EEPROM interface driven as masters drive it (spec-notes §esc.sii-if, §sii.fixed).

use crate::segment_support;

use ecat_wire::command::Command;
use ecat_wire::sii::set_alias;
use segment_support::*;

const S: u16 = 0x1001;

/// SOEM's read: command + address in one 6-byte write, poll busy, read the data.
fn read(bench: &mut Bench, word: u16, len: usize) -> (u16, Vec<u8>) {
    let w = word.to_le_bytes();
    let r = bench.send(&[
        fp(
            Command::Fpwr,
            S,
            0x0502,
            &[0x00, 0x01, w[0], w[1], 0x00, 0x00],
        ),
        fp(Command::Fprd, S, 0x0502, &[0, 0]),
        fp(Command::Fprd, S, 0x0508, &vec![0; len]),
    ]);
    assert_eq!((r[0].wkc, r[1].wkc, r[2].wkc), (1, 1, 1));
    (r[1].u16(), r[2].data.clone())
}

/// The write procedure: data word, then control 0x0201 (or `control`) with the address.
fn write(bench: &mut Bench, word: u16, value: [u8; 2], control: u16) -> u16 {
    let w = word.to_le_bytes();
    let c = control.to_le_bytes();
    let r = bench.send(&[
        fp(Command::Fpwr, S, 0x0508, &value),
        fp(Command::Fpwr, S, 0x0502, &[c[0], c[1], w[0], w[1], 0, 0]),
        fp(Command::Fprd, S, 0x0502, &[0, 0]),
    ]);
    r[2].u16()
}

#[test]
fn c3_read_of_the_identity_8_bytes() {
    let mut bench = Bench::new(1);
    bench.assign_addresses();
    // SOEM first hands the EEPROM to the master.
    bench.one(fp(Command::Fpwr, S, 0x0500, &[0x02]));
    bench.one(fp(Command::Fpwr, S, 0x0500, &[0x00]));
    let (status, data) = read(&mut bench, 0x0008, 8);
    assert_eq!(status & 0x8000, 0, "never busy");
    assert_eq!(status & 0x7800, 0, "no error");
    assert_eq!(status & 0x0040, 0x0040, "8-byte reads");
    assert_eq!(
        data,
        [0x02, 0, 0, 0, 0x34, 0x12, 0, 0],
        "vendor 2, product 0x1234"
    );
    let (_, data) = read(&mut bench, 0x0018, 8);
    assert_eq!(
        data,
        [0x00, 0x10, 0x80, 0x00, 0x80, 0x10, 0x80, 0x00],
        "mailboxes"
    );
    let words = (bench.esc(0).sii().len() / 2) as u16;
    let (_, data) = read(&mut bench, words - 2, 8);
    assert_eq!(data[4..], [0xFF; 4], "beyond the image");
}

#[test]
fn four_byte_reads() {
    let mut bench = Bench::with(1, |_, c| c.eeprom_read_8_bytes = false);
    bench.assign_addresses();
    let (status, data) = read(&mut bench, 0x000A, 4);
    assert_eq!(status & 0x0040, 0);
    assert_eq!(data, [0x34, 0x12, 0, 0]);
}

#[test]
fn writes_need_the_enable_bit_and_change_the_image() {
    let mut bench = Bench::new(1);
    bench.assign_addresses();
    let status = write(&mut bench, 0x0020, [0xCD, 0xAB], 0x0200);
    assert_eq!(status & 0x4000, 0x4000, "write enable error");
    assert_eq!(read(&mut bench, 0x0020, 8).1[..2], [0, 0]);
    let status = write(&mut bench, 0x0020, [0xCD, 0xAB], 0x0201);
    assert_eq!(status & 0x7801, 0, "done; enable cleared; errors cleared");
    assert_eq!(read(&mut bench, 0x0020, 8).1[..2], [0xCD, 0xAB]);
    assert_eq!(bench.esc(0).sii()[0x40..0x42], [0xCD, 0xAB]);
}

#[test]
fn new_alias_survives_a_power_cycle() {
    let mut bench = Bench::new(1);
    bench.assign_addresses();
    let mut image = bench.esc(0).sii().to_vec();
    set_alias(&mut image, 0x0BAD).unwrap();
    // IgH writes words 4 and 7 (alias and checksum).
    for word in [4u16, 7] {
        let at = usize::from(word) * 2;
        let status = write(&mut bench, word, [image[at], image[at + 1]], 0x0201);
        assert_eq!(status & 0x7800, 0);
    }
    assert_eq!(
        bench.esc(0).station_alias(),
        0,
        "the register changes only on load"
    );
    bench.segment.power_cycle(0);
    assert_eq!(bench.esc(0).station_alias(), 0x0BAD);
    assert_eq!(bench.esc(0).station_address(), 0, "registers reset");
    assert_eq!(bench.esc(0).sii(), image.as_slice(), "SII kept");
}

#[test]
fn bad_checksum_sets_bit_11_and_leaves_the_pdi_off() {
    let mut bench = Bench::empty();
    let mut image = sii(0);
    image[8] = 0x55; // alias changed, checksum not
    bench.push(Default::default(), image);
    bench.assign_addresses();
    let r = bench.one(fp(Command::Fprd, S, 0x0502, &[0, 0]));
    assert_eq!(r.u16() & 0x0800, 0x0800);
    let r = bench.one(fp(Command::Fprd, S, 0x0110, &[0, 0]));
    assert_eq!(r.u16() & 0x0001, 0, "DL status: PDI not operational");
    assert_eq!(bench.one(fp(Command::Fprd, S, 0x0012, &[0, 0])).u16(), 0);
    // The master repairs the checksum and reloads.
    let repaired = sii(0x0055);
    let status = write(&mut bench, 7, [repaired[14], repaired[15]], 0x0201);
    assert_eq!(status & 0x4000, 0);
    bench.one(fp(Command::Fpwr, S, 0x0502, &[0x00, 0x04]));
    let r = bench.one(fp(Command::Fprd, S, 0x0502, &[0, 0]));
    assert_eq!(r.u16() & 0x0800, 0, "reload with a good checksum");
    assert_eq!(bench.esc(0).station_alias(), 0x0055);
    assert!(bench.esc(0).pdi_operational());
}
