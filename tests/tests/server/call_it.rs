//! Runs every `ecat`, `grpcurl` and `curl` line of `docs/call-it.md` in order against
//! `ecatd --simulate`, as printed (only the addresses swapped for the test's own), and checks
//! the shape of what each prints: JSON from grpcurl and the REST API, JSON from `ecat --json`,
//! the file for `-o`. A line that stops working fails here, so the page cannot rot.

use crate::server_support;

use std::path::Path;
use std::process::Command;

use serde_json::Value;
use server_support::{Ecatd, bin_dir, grpcurl_path};

/// One operation of the page: its heading and its lines.
struct Operation {
    heading: String,
    lines: Vec<String>,
}

fn operations(page: &str) -> Vec<Operation> {
    let section = page
        .split("## Operations")
        .nth(1)
        .and_then(|rest| rest.split("\n## ").next())
        .expect("the page has an Operations section");
    let mut operations: Vec<Operation> = Vec::new();
    let mut in_block = false;
    for line in section.lines() {
        if let Some(heading) = line.strip_prefix("### ") {
            operations.push(Operation {
                heading: heading.to_owned(),
                lines: Vec::new(),
            });
        } else if line.starts_with("```") {
            in_block = !in_block;
        } else if in_block && !line.trim().is_empty() {
            operations
                .last_mut()
                .expect("a code block under a heading")
                .lines
                .push(line.to_owned());
        }
    }
    operations
}

fn json_values(text: &str) -> Vec<Value> {
    serde_json::Deserializer::from_str(text)
        .into_iter::<Value>()
        .collect::<Result<_, _>>()
        .unwrap_or_default()
}

/// The file a line writes with `-o FILE`, if any.
fn output_file(line: &str) -> Option<&str> {
    let mut words = line.split_whitespace();
    while let Some(word) = words.next() {
        if word == "-o" {
            return words.next();
        }
    }
    None
}

fn run(line: &str, ecatd: &Ecatd, dir: &Path) -> (bool, String, String) {
    let line = line
        .replace("localhost:50051", &ecatd.grpc.to_string())
        .replace("localhost:8080", ecatd.http.trim_start_matches("http://"));
    let path = format!(
        "{}:{}:{}",
        bin_dir().display(),
        grpcurl_path().parent().unwrap().display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let output = Command::new("sh")
        .args(["-c", &line])
        .env("PATH", path)
        .env("ECAT_ADDRESS", format!("http://{}", ecatd.grpc))
        .env_remove("ECAT_TOKEN")
        .current_dir(dir)
        .output()
        .expect("sh runs");
    (
        output.status.success(),
        String::from_utf8_lossy(&output.stdout).into_owned(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

#[test]
fn every_line_of_the_call_it_page_works_as_printed() {
    let page =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/call-it.md"))
            .expect("docs/call-it.md");
    let operations = operations(&page);
    assert!(operations.len() >= 15, "{} operations", operations.len());
    let ecatd = Ecatd::start(&[]);
    let dir = std::env::temp_dir().join(format!("ecatd-call-it-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for op in &operations {
        let tools: Vec<&str> = op
            .lines
            .iter()
            .map(|l| l.split_whitespace().next().unwrap_or(""))
            .collect();
        assert_eq!(
            tools,
            ["ecat", "grpcurl", "curl"],
            "{}: one line each",
            op.heading
        );
        for line in &op.lines {
            let (ok, stdout, stderr) = run(line, &ecatd, &dir);
            assert!(ok, "{}: `{line}` failed:\n{stdout}{stderr}", op.heading);
            let what = format!("{}: `{line}` printed:\n{stdout}", op.heading);
            if let Some(file) = output_file(line) {
                let written = std::fs::metadata(dir.join(file)).map(|m| m.len());
                assert!(written.is_ok_and(|n| n > 0), "{what}\n(no {file})");
            } else if line.starts_with("ecat ") {
                // A write prints nothing; its shape is checked with --json below.
            } else if line.starts_with("grpcurl") || line.contains("/api/v1/") {
                assert!(!json_values(&stdout).is_empty(), "{what}");
            } else {
                assert!(!stdout.trim().is_empty(), "{what}");
            }
            if line.starts_with("ecat ") && output_file(line).is_none() {
                let json = line.replacen("ecat ", "ecat --json ", 1);
                let (ok, stdout, stderr) = run(&json, &ecatd, &dir);
                assert!(ok, "`{json}` failed: {stderr}");
                assert_eq!(json_values(&stdout).len(), 1, "`{json}` printed:\n{stdout}");
            }
        }
    }
    // The FoE lines fetched the same file.
    assert_eq!(
        std::fs::read(dir.join("firmware.bin")).unwrap(),
        std::fs::read(dir.join("firmware-rest.bin")).unwrap()
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
