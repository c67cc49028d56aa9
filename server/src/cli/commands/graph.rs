//! `ecat graph`: the topology as a Graphviz digraph, the parent of each slave found as
//! the masters do it, from the ports that carry communication in DL status 0x0110 (ETG.1000.4,
//! spec-notes §esc.dl): a slave's open ports beyond its entry port lead, in ring order, to the
//! slaves that follow it.

use serde_json::json;

use super::slaves::display_name;
use crate::Run;
use crate::failure::Failure;
use crate::out::{Out, out};
use crate::session::Session;

/// `ecat graph`.
#[derive(Debug, clap::Args)]
pub struct Graph {}

impl Run for Graph {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let slaves = session.slaves().await?;
        let c = session.clients().await?;
        let mut open = Vec::new();
        for s in &slaves {
            let details = super::esc::details(c, s).await?;
            let active = details
                .ports
                .iter()
                .filter(|p| p.communication && !p.loop_closed)
                .count();
            open.push(active.saturating_sub(1));
        }
        let mut edges = Vec::new();
        let mut free = vec![0usize; slaves.len()];
        for i in 0..slaves.len() {
            // The nearest slave before it with a free downstream port; the master for the first.
            let parent = (0..i).rev().find(|&j| free[j] > 0);
            if let Some(j) = parent {
                free[j] -= 1;
            }
            free[i] = open[i];
            edges.push(parent);
        }
        let mut dot = String::from(
            "digraph ethercat {\n  rankdir=LR;\n  master [shape=box, label=\"Master0\"];\n",
        );
        for s in &slaves {
            dot.push_str(&format!(
                "  slave{} [label=\"{}\\n{}\"];\n",
                s.position,
                s.position,
                display_name(s).replace('"', "'")
            ));
        }
        for (i, parent) in edges.iter().enumerate() {
            match parent {
                Some(j) => dot.push_str(&format!("  slave{j} -> slave{i};\n")),
                None => dot.push_str(&format!("  master -> slave{i};\n")),
            }
        }
        dot.push('}');
        let json = json!({"edges": edges.iter().enumerate().map(|(i, p)| json!({"slave": i, "parent": p})).collect::<Vec<_>>()});
        Ok(out(json, dot))
    }
}
