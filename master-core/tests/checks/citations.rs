//! `scripts/check-citations` (run by `scripts/test` over every tracked file) reads a
//! citation that runs over a line break as one: checked here on small files of its own.
//! The bad citations below are on purpose: check-citations: skip.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

fn script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/check-citations")
}

/// Runs the script on one file holding `text`: its exit success and its complaints.
fn check(name: &str, text: &str) -> (bool, String) {
    let dir = std::env::temp_dir().join(format!("ecatd-citations-{}", std::process::id()));
    fs::create_dir_all(&dir).unwrap();
    let file = dir.join(name);
    fs::write(&file, text).unwrap();
    let out = Command::new("bash")
        .arg(script())
        .arg(&file)
        .output()
        .unwrap();
    fs::remove_file(&file).unwrap();
    let _ = fs::remove_dir(&dir);
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn citations_over_a_line_break_are_read_whole() {
    let good = "//! The states (spec-notes\n//! §al), and the layout in ETG.1000.4\n\
                /// Table 12: each field.\n";
    assert_eq!(check("good.rs", good), (true, String::new()));
}

#[test]
fn a_bad_citation_over_a_line_break_is_reported_where_it_starts() {
    let bad = "//! Intro.\n//! As spec-notes\n//! §no-such-key says.\n\
               /// The layout is in\n/// Table 12. ETG.1000.4 is elsewhere.\n\
               /// From the digest\n/// §3.\n";
    let (ok, complaints) = check("bad.rs", bad);
    assert!(!ok);
    assert!(
        complaints.contains("bad.rs:3: §no-such-key"),
        "{complaints}"
    );
    assert!(
        complaints.contains("table without its ETG document") && complaints.contains("bad.rs:5:"),
        "{complaints}"
    );
    assert!(
        complaints.contains("old citation") && complaints.contains("bad.rs:6:"),
        "{complaints}"
    );
}

#[test]
fn a_markdown_paragraph_is_one_text() {
    let good = "A list of the\nregisters is in ETG.1000.4\nTable 31, as spec-notes §al and\n§esc.watchdog say.\n";
    assert!(check("good.md", good).0);
    let bad = "ETG.1000.4 has it.\n\nTable 31 is another story.\n";
    let (ok, complaints) = check("bad.md", bad);
    assert!(!ok && complaints.contains("bad.md:3:"), "{complaints}");
}
