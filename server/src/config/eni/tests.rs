use super::*;
use crate::config::Config;

fn data(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/data/config")
        .join(name)
}

#[test]
fn the_sample_eni_is_the_same_machine_as_the_sample_toml() {
    let eni = load(&data("default-segment.eni.xml")).unwrap();
    let text = std::fs::read_to_string(data("drive-500us.toml")).unwrap();
    let toml: Config = toml::from_str(&text).unwrap();
    assert_eq!(eni.cycle, Some(toml.bus.cycle));
    let setups =
        |slaves: &[SlaveEntry]| -> Vec<_> { slaves.iter().map(|s| s.setup().unwrap()).collect() };
    assert_eq!(setups(&eni.slaves), setups(&toml.slave));
    // What is not used is listed, what is used is not.
    let unused = eni.unused.join(" ");
    for listed in [
        "Master (1)",
        "ProcessImage (1)",
        "Slave/Mailbox/Send",
        "Slave/ProcessData/Send",
        "Slave/Mailbox/CoE/InitCmds/InitCmd (1)",
        "Slave/DC/ReferenceClock (1)",
    ] {
        assert!(unused.contains(listed), "{listed} not in {unused}");
    }
    assert!(
        !unused.contains("RxPdo") && !unused.contains("SoE"),
        "{unused}"
    );
}

#[test]
fn bad_enis_name_the_file_line_and_element() {
    let no_product = "<EtherCATConfig><Config>\n<Slave><Info>\n<VendorId>2</VendorId>\n</Info></Slave></Config></EtherCATConfig>";
    assert_eq!(
        parse(no_product, "x.xml").unwrap_err(),
        "x.xml:2: <Info>: <ProductCode> is missing"
    );
    let bad_number = "<EtherCATConfig><Config><Slave><Info><VendorId>2</VendorId>\n<ProductCode>#xZZ</ProductCode></Info></Slave></Config></EtherCATConfig>";
    assert_eq!(
        parse(bad_number, "x.xml").unwrap_err(),
        "x.xml:2: <ProductCode>: \"#xZZ\" is not a number"
    );
    assert!(
        parse("<Other/>", "x.xml")
            .unwrap_err()
            .contains("<EtherCATConfig>")
    );
    assert!(
        parse("<EtherCATConfig>", "x.xml")
            .unwrap_err()
            .contains("not XML")
    );
    let bad_transition = "<EtherCATConfig><Config><Slave><Info><VendorId>2</VendorId><ProductCode>1</ProductCode></Info>\n<Mailbox><CoE><InitCmds>\n<InitCmd><Transition>XX</Transition><Index>1</Index><SubIndex>0</SubIndex><Data>00</Data></InitCmd></InitCmds></CoE></Mailbox></Slave></Config></EtherCATConfig>";
    let err = parse(bad_transition, "x.xml").unwrap_err();
    assert!(
        err.starts_with("x.xml:3: <InitCmd>: transition \"XX\""),
        "{err}"
    );
}
