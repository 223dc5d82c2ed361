//! One subject's retained state in the cluster's KV bucket: which site has it, its name, and
//! the `skeleton` (and, for characters, `mapping`) messages its clients get.

use anyhow::Context;
use rigcast_protocol::control::BoneInfo;
use serde::{Deserialize, Serialize};

/// The bucket value of one subject (JSON).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SubjectEntry {
    /// The node that produces it.
    pub site: String,
    /// Its name on that node.
    pub name: String,
    /// Its bones, as in its `skeleton` message.
    pub bones: Vec<BoneInfo>,
    /// Its `mapping` message as JSON (characters only).
    #[serde(default)]
    pub mapping: Option<serde_json::Value>,
}

impl SubjectEntry {
    /// The entry of a subject: its bones as its `skeleton` message lists them and its
    /// `mapping` message (characters only).
    pub fn new(
        site: &str,
        name: &str,
        bones: Vec<BoneInfo>,
        mapping: Option<serde_json::Value>,
    ) -> SubjectEntry {
        SubjectEntry {
            site: site.to_string(),
            name: name.to_string(),
            bones,
            mapping,
        }
    }

    /// Reads a bucket value.
    pub fn parse(bytes: &[u8]) -> anyhow::Result<SubjectEntry> {
        serde_json::from_slice(bytes).context("not a rigcast subject entry")
    }

    /// The bucket key: `SITE.NAME` with the name made a NATS token.
    pub fn key(&self) -> String {
        format!("{}.{}", self.site, token(&self.name))
    }

    /// The name the subject gets on a node that relays it.
    pub fn relayed_name(&self) -> String {
        format!("{}@{}", self.name, self.site)
    }
}

/// `text` as one NATS subject token / KV key part: letters, digits, `-` and `_` kept, every
/// other character (dots, wildcards, spaces, non-ASCII) replaced by `_`.
pub fn token(text: &str) -> String {
    text.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_become_single_tokens() {
        assert_eq!(token("walk.bvh > 2*"), "walk_bvh___2_");
        assert_eq!(token("Mannequin-01_b"), "Mannequin-01_b");
        assert_eq!(token("歩く"), "__");
    }

    #[test]
    fn an_entry_round_trips_through_the_bucket_format() {
        let bones = vec![BoneInfo {
            name: "Hips".into(),
            parent: None,
            rest_translation: [0.0, 1.0, 0.0],
            rest_rotation: [0.0, 0.0, 0.0, 1.0],
            translated: true,
        }];
        let e = SubjectEntry::new("a", "walk.1", bones, None);
        assert_eq!(e.key(), "a.walk_1");
        assert_eq!(e.relayed_name(), "walk.1@a");
        let back = SubjectEntry::parse(&serde_json::to_vec(&e).unwrap()).unwrap();
        assert_eq!(back, e);
        assert!(SubjectEntry::parse(b"{}").is_err());
    }
}
