//! `deploy/ecatd.toml.example` is a configuration the server's loader accepts, and it names
//! every key the loader knows: a key added to the configuration without an example line
//! fails here.

use std::path::Path;

use server::config::{Config, Segment};

fn example() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../deploy/ecatd.toml.example");
    std::fs::read_to_string(&path).unwrap_or_else(|err| panic!("{}: {err}", path.display()))
}

/// Every key of `shown` (recursively, through tables and arrays of tables) is in `documented`.
fn keys_documented(shown: &toml::Value, documented: &toml::Value, at: &str) {
    match (shown, documented) {
        (toml::Value::Table(shown), toml::Value::Table(documented)) => {
            for (key, value) in shown {
                let path = format!("{at}{key}");
                let Some(example) = documented.get(key) else {
                    panic!("deploy/ecatd.toml.example does not document `{path}`");
                };
                keys_documented(value, example, &format!("{path}."));
            }
        }
        (toml::Value::Array(shown), toml::Value::Array(documented)) => {
            // Tables of an array: each shown table against the union of the example's.
            for value in shown.iter().filter(|v| v.is_table()) {
                let mut union = toml::Table::new();
                for example in documented.iter().filter_map(|v| v.as_table()) {
                    union.extend(example.clone());
                }
                keys_documented(value, &toml::Value::Table(union), at);
            }
        }
        _ => {}
    }
}

#[test]
fn the_example_parses_with_the_values_it_shows() {
    let config: Config = toml::from_str(&example()).expect("the example parses");
    assert_eq!(
        config.segment,
        Some(Segment::Iface {
            name: "eth1".into()
        })
    );
    assert_eq!(config.http_listen, "127.0.0.1:8080".parse().unwrap());
    assert_eq!(config.tokens.len(), 2);
    assert_eq!(config.watch.len(), 2);
    let gateway = config.gateway.as_ref().expect("[gateway]");
    assert_eq!(gateway.allow.len(), 2);
    assert_eq!(gateway.retry_window_ms, 1000);
    assert!(config.tls.is_some());
    assert_eq!(config.shutdown_timeout_ms, 5000);
}

#[test]
fn the_example_documents_every_key() {
    let text = example();
    let config: Config = toml::from_str(&text).expect("the example parses");
    // What the loader knows, as it writes it back (every field the example sets, and every
    // field with a default).
    let shown: toml::Value = toml::from_str(&config.to_toml()).expect("to_toml parses");
    let documented: toml::Value = toml::from_str(&text).unwrap();
    keys_documented(&shown, &documented, "");
}
