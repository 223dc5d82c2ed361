//! The mapping table: plain, serialisable data.

use serde::{Deserialize, Serialize};

use crate::error::RetargetError;
use crate::skeleton::{BoneId, Skeleton};

/// One source bone driving a target bone.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SourceRef {
    /// Which source skeleton (index into the list of inputs; 0 when there is one source).
    pub input: u16,
    /// The bone on that source skeleton.
    pub bone: BoneId,
    /// Blend weight (normalised over an entry's sources when applied).
    pub weight: f32,
}

/// Per-bone options (seed 004 §4.2.3).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BoneOptions {
    /// Play this bone's motion late by this many seconds (e.g. a tail following the spine).
    pub delay_secs: f32,
    /// Invert the rotation angle.
    pub reverse: bool,
    /// Overall influence 0..=1 (0 holds the bone at rest).
    pub weight: f32,
}

impl Default for BoneOptions {
    fn default() -> Self {
        BoneOptions {
            delay_secs: 0.0,
            reverse: false,
            weight: 1.0,
        }
    }
}

/// How one target bone is driven.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TargetEntry {
    /// Source bones, primary first.
    pub sources: Vec<SourceRef>,
    /// Per-bone options.
    pub options: BoneOptions,
    /// Match score from the automatic mapper (higher is better; 0 for user overrides).
    pub score: f32,
    /// Short human-readable reasons that decided the match, e.g. `"side=left"`, `"name:forearm"`.
    pub evidence: Vec<String>,
    /// 0..=1, how sure the automatic mapper is (its margin over the best alternative and
    /// the analyses' confidence in both bones' roles); 1 for user overrides.
    #[serde(default = "full_confidence")]
    pub confidence: f32,
}

fn full_confidence() -> f32 {
    1.0
}

/// A target bone a person should check: low confidence, a runner-up close behind, or a core
/// bone left without a source.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Flag {
    /// The target bone.
    pub bone: BoneId,
    /// Its entry's confidence (0 when unmapped).
    pub confidence: f32,
    /// Why, for a person: e.g. `"the runner-up is 1.5 points behind"`.
    pub reason: String,
}

impl TargetEntry {
    /// The primary (first) source bone.
    pub fn primary(&self) -> Option<SourceRef> {
        self.sources.first().copied()
    }
}

/// For every target bone, its entry or `None` (unmapped: held at rest).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MappingTable {
    /// Indexed by target [`BoneId`].
    pub entries: Vec<Option<TargetEntry>>,
    /// Bones to check, in target bone order (the automatic mapper fills it; overrides remove
    /// the bones they set).
    #[serde(default)]
    pub flagged: Vec<Flag>,
}

impl MappingTable {
    /// A table with every one of `num_target_bones` unmapped.
    pub fn empty(num_target_bones: usize) -> Self {
        MappingTable {
            entries: vec![None; num_target_bones],
            flagged: Vec::new(),
        }
    }

    /// Maps target bones to source bones with the same name (a baseline and a test helper).
    pub fn by_exact_name(source: &Skeleton, target: &Skeleton) -> Self {
        let mut t = MappingTable::empty(target.num_bones());
        for tb in target.bone_ids() {
            if let Some(sb) = source.bone(target.name(tb)) {
                t.entries[tb.index()] = Some(TargetEntry {
                    sources: vec![SourceRef {
                        input: 0,
                        bone: sb,
                        weight: 1.0,
                    }],
                    options: BoneOptions::default(),
                    score: 0.0,
                    evidence: vec!["name:exact".into()],
                    confidence: 1.0,
                });
            }
        }
        t
    }

    /// Entry of one target bone.
    pub fn get(&self, target: BoneId) -> Option<&TargetEntry> {
        self.entries.get(target.index()).and_then(|e| e.as_ref())
    }

    /// The flag of one target bone, if it is flagged.
    pub fn flag(&self, target: BoneId) -> Option<&Flag> {
        self.flagged.iter().find(|f| f.bone == target)
    }

    /// Number of mapped target bones.
    pub fn num_mapped(&self) -> usize {
        self.entries.iter().filter(|e| e.is_some()).count()
    }

    /// Checks the table against the skeletons it will be applied to (`sources[input]`).
    pub fn validate(&self, sources: &[&Skeleton], target: &Skeleton) -> Result<(), RetargetError> {
        if self.entries.len() != target.num_bones() {
            return Err(RetargetError::InvalidMapping {
                reason: format!(
                    "table has {} entries but the target has {} bones",
                    self.entries.len(),
                    target.num_bones()
                ),
            });
        }
        for (ti, e) in self.entries.iter().enumerate() {
            let Some(e) = e else { continue };
            for s in &e.sources {
                let Some(skel) = sources.get(s.input as usize) else {
                    return Err(RetargetError::InvalidMapping {
                        reason: format!(
                            "target bone {ti} refers to source input {} which does not exist",
                            s.input
                        ),
                    });
                };
                if s.bone.index() >= skel.num_bones() {
                    return Err(RetargetError::InvalidMapping {
                        reason: format!(
                            "target bone {ti} refers to source bone {} of {}",
                            s.bone.0,
                            skel.num_bones()
                        ),
                    });
                }
                if !(s.weight.is_finite() && s.weight >= 0.0) {
                    return Err(RetargetError::InvalidMapping {
                        reason: format!("target bone {ti} has a bad weight {}", s.weight),
                    });
                }
            }
        }
        Ok(())
    }
}
