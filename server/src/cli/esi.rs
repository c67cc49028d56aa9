//! An ESI fragment (ETG.2000, the EtherCAT Slave Information XML) generated from a slave's
//! SII image, as IgH's `ethercat xml` prints one: the vendor, the device's type (product
//! code, revision) and name, its SyncManagers, its RxPDOs and TxPDOs with their entries
//! (from the SII's SYNCM, RXPDO and TXPDO categories: ETG.2010, spec-notes
//! §sii.categories), and its mailbox protocols (SII word 0x1C, spec-notes §sii.fixed).

use std::fmt::Write;

use master_core::wire::sii::SiiImage;
use master_core::wire::sii::fixed::MailboxProtocols;
use master_core::wire::sii::pdo::{Pdo, PdoFlags};

/// The ESI `<EtherCATInfo>` for the slave whose SII is `image`; `title` goes in a comment.
pub fn from_sii(image: &[u8], title: &str) -> Result<String, String> {
    let sii = SiiImage::parse(image).map_err(|err| format!("the SII does not parse: {err}"))?;
    let f = &sii.fixed;
    let mut x = String::new();
    // Writing into a String cannot fail.
    let _ = writeln!(x, "<?xml version=\"1.0\" encoding=\"UTF-8\"?>");
    let _ = writeln!(x, "<EtherCATInfo>");
    let _ = writeln!(x, "  <!-- {} -->", escape(&title.replace("--", "- -")));
    let _ = writeln!(x, "  <Vendor>");
    let _ = writeln!(x, "    <Id>#x{:08x}</Id>", f.vendor_id);
    let _ = writeln!(x, "  </Vendor>");
    let _ = writeln!(x, "  <Descriptions>");
    let _ = writeln!(x, "    <Devices>");
    let _ = writeln!(x, "      <Device>");
    let order = sii.order().or(sii.name()).unwrap_or("");
    let _ = writeln!(
        x,
        "        <Type ProductCode=\"#x{:08x}\" RevisionNo=\"#x{:08x}\">{}</Type>",
        f.product_code,
        f.revision,
        escape(order)
    );
    if let Some(name) = sii.name() {
        let _ = writeln!(x, "        <Name>{}</Name>", escape(name));
    }
    for sm in &sii.syncm {
        let _ = writeln!(
            x,
            "        <Sm Enable=\"{}\" StartAddress=\"#x{:04x}\" ControlByte=\"#x{:02x}\" DefaultSize=\"{}\" />",
            u8::from(sm.enable.enable()),
            sm.start,
            sm.control,
            sm.length
        );
    }
    for pdo in &sii.rxpdo {
        pdo_xml(&mut x, &sii, pdo, "RxPdo");
    }
    for pdo in &sii.txpdo {
        pdo_xml(&mut x, &sii, pdo, "TxPdo");
    }
    let protocols = f.mailbox_protocols;
    if protocols.0 != 0 {
        let _ = writeln!(x, "        <Mailbox>");
        for (flag, element) in [
            (MailboxProtocols::AOE, "AoE"),
            (MailboxProtocols::EOE, "EoE"),
            (MailboxProtocols::COE, "CoE"),
            (MailboxProtocols::FOE, "FoE"),
            (MailboxProtocols::SOE, "SoE"),
            (MailboxProtocols::VOE, "VoE"),
        ] {
            if protocols.contains(flag) {
                let _ = writeln!(x, "          <{element} />");
            }
        }
        let _ = writeln!(x, "        </Mailbox>");
    }
    let _ = writeln!(x, "      </Device>");
    let _ = writeln!(x, "    </Devices>");
    let _ = writeln!(x, "  </Descriptions>");
    let _ = write!(x, "</EtherCATInfo>");
    Ok(x)
}

fn pdo_xml(x: &mut String, sii: &SiiImage<'_>, pdo: &Pdo, element: &str) {
    let mut attributes = String::new();
    if let Some(sm) = pdo.assigned_sm() {
        let _ = write!(attributes, " Sm=\"{sm}\"");
    }
    if pdo.flags.contains(PdoFlags::FIXED_CONTENT) {
        attributes.push_str(" Fixed=\"1\"");
    }
    if pdo.flags.contains(PdoFlags::MANDATORY) {
        attributes.push_str(" Mandatory=\"1\"");
    }
    let _ = writeln!(x, "        <{element}{attributes}>");
    let _ = writeln!(x, "          <Index>#x{:04x}</Index>", pdo.index);
    let _ = writeln!(
        x,
        "          <Name>{}</Name>",
        escape(sii.pdo_name(pdo).unwrap_or(""))
    );
    for entry in &pdo.entries {
        let _ = writeln!(x, "          <Entry>");
        let _ = writeln!(x, "            <Index>#x{:04x}</Index>", entry.index);
        if !entry.is_gap() {
            let _ = writeln!(x, "            <SubIndex>{}</SubIndex>", entry.subindex);
        }
        let _ = writeln!(x, "            <BitLen>{}</BitLen>", entry.bit_length);
        if !entry.is_gap() {
            if let Some(name) = sii.string(entry.name_idx) {
                let _ = writeln!(x, "            <Name>{}</Name>", escape(name));
            }
            if let Some(ty) = esi_type(entry.data_type, entry.bit_length) {
                let _ = writeln!(x, "            <DataType>{ty}</DataType>");
            }
        }
        let _ = writeln!(x, "          </Entry>");
    }
    let _ = writeln!(x, "        </{element}>");
}

/// The ESI name of a CoE data type (ETG.2000's base types).
fn esi_type(code: u8, bits: u8) -> Option<String> {
    Some(match code {
        0x01 => "BOOL".into(),
        0x02 => "SINT".into(),
        0x03 => "INT".into(),
        0x04 => "DINT".into(),
        0x05 => "USINT".into(),
        0x06 => "UINT".into(),
        0x07 => "UDINT".into(),
        0x08 => "REAL".into(),
        0x09 => format!("STRING({})", bits / 8),
        0x11 => "LREAL".into(),
        0x15 => "LINT".into(),
        0x1B => "ULINT".into(),
        0x30..=0x37 => format!("BIT{}", code - 0x2F),
        _ => return None,
    })
}

/// Text with XML's special characters escaped.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}
