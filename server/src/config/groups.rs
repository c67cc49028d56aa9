//! `[[group]]`: slaves whose process data goes at a period of their own, a multiple of
//! the bus cycle (see `master_core::master::SlaveGroup`).

use std::time::Duration;

use serde::{Deserialize, Serialize};

use master_core::master::SlaveGroup;

use super::duration;

/// `[[group]]`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GroupEntry {
    /// A label for messages.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// How often its process data is exchanged: a whole multiple of `[bus] cycle`.
    #[serde(with = "duration")]
    pub period: Duration,
    /// Ring positions of its slaves.
    pub members: Vec<u16>,
}

/// The master's groups, checked against the cycle: every period a multiple of it, no
/// slave in two groups, no empty group.
pub fn groups(entries: &[GroupEntry], cycle: Duration) -> Result<Vec<SlaveGroup>, String> {
    let mut seen = std::collections::BTreeMap::new();
    let mut groups = Vec::new();
    for (i, group) in entries.iter().enumerate() {
        let label = format!("[[group]] #{}", i + 1);
        if !duration::is_multiple(group.period, cycle) {
            return Err(format!(
                "{label}: period {:?} is not a whole multiple of the cycle {:?}",
                duration::show(group.period),
                duration::show(cycle)
            ));
        }
        if group.members.is_empty() {
            return Err(format!("{label}: members is empty"));
        }
        for &member in &group.members {
            if let Some(other) = seen.insert(member, i + 1) {
                return Err(format!(
                    "{label}: position {member} is already in [[group]] #{other}"
                ));
            }
        }
        groups.push(SlaveGroup {
            positions: group.members.clone(),
            period: group.period,
        });
    }
    Ok(groups)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn periods_are_multiples_of_the_cycle_and_members_unique() {
        let cycle = Duration::from_micros(500);
        let group = |ms: u64, members: Vec<u16>| GroupEntry {
            name: None,
            period: Duration::from_millis(ms),
            members,
        };
        assert_eq!(groups(&[group(2, vec![1, 2])], cycle).unwrap().len(), 1);
        let err = groups(&[group(2, vec![1]), group(4, vec![1])], cycle).unwrap_err();
        assert!(err.contains("already in [[group]] #1"), "{err}");
        let odd = GroupEntry {
            period: Duration::from_micros(750),
            ..group(1, vec![3])
        };
        assert!(groups(&[odd], cycle).unwrap_err().contains("multiple"));
    }
}
