//! Mapping files: a small, hand-editable TOML format (documented in `retarget/MAPPING.md`).
//!
//! ```toml
//! version = 1
//! [bones."LeftUpperArm"]              # target bone name
//! source = "mixamorig:LeftArm"        # one source bone (input 0)
//! [bones."Tail1"]
//! sources = [ { bone = "Spine", weight = 0.5 }, { bone = "Hips", input = 1, weight = 0.5 } ]
//! delay_secs = 0.2                    # per-bone options (all optional)
//! reverse = false
//! weight = 1.0
//! [bones."Antenna"]
//! unmapped = true                     # hold at rest even if the mapper found something
//! ```
//!
//! A file may be partial: [`apply_overrides`] merges it over an automatic table, touching only
//! the bones it names.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::table::{BoneOptions, MappingTable, SourceRef, TargetEntry};
use crate::skeleton::Skeleton;

/// Current format version.
pub const MAPPING_FILE_VERSION: u32 = 1;

/// Problems with a mapping file. Messages name the bone and, for syntax errors, the line.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum MappingFileError {
    /// Not valid TOML or not the expected shape (the message carries line and column).
    #[error("mapping file is not valid: {message}")]
    Parse {
        /// parser message with position
        message: String,
    },
    /// A version this build does not know.
    #[error("mapping file version {found} is not supported (expected {expected})")]
    Version {
        /// version in the file
        found: u32,
        /// version supported
        expected: u32,
    },
    /// A target bone name that the target skeleton does not have.
    #[error("mapping file names target bone {name:?}, which the target skeleton does not have")]
    UnknownTargetBone {
        /// the name
        name: String,
    },
    /// A source bone name that the source skeleton does not have.
    #[error("mapping for target bone {target:?} names source bone {name:?}, which source input {input} does not have")]
    UnknownSourceBone {
        /// target bone
        target: String,
        /// missing source bone
        name: String,
        /// source input index
        input: u16,
    },
    /// The table to merge into was made for a skeleton with a different number of bones
    /// (e.g. a stale cache entry), so target bone names cannot index it.
    #[error("mapping table has {entries} entries but the target skeleton has {bones} bones")]
    TableSize {
        /// entries in the table
        entries: usize,
        /// bones in the target skeleton
        bones: usize,
    },
    /// A weight / delay that is negative or not finite.
    #[error("mapping for target bone {target:?} has a bad value: {what}")]
    BadValue {
        /// target bone
        target: String,
        /// which value and why
        what: String,
    },
}

/// One source bone in a file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FileSource {
    /// Source bone name.
    pub bone: String,
    /// Source input (0 when there is one source).
    #[serde(default)]
    pub input: u16,
    /// Blend weight.
    #[serde(default = "one")]
    pub weight: f32,
}

fn one() -> f32 {
    1.0
}

/// One target bone in a file.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FileBone {
    /// Shorthand for a single source bone on input 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<String>,
    /// Several source bones with weights.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sources: Vec<FileSource>,
    /// Explicitly unmapped (held at rest).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub unmapped: bool,
    /// Per-bone delay, seconds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub delay_secs: Option<f32>,
    /// Per-bone reverse.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reverse: Option<bool>,
    /// Per-bone influence 0..=1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weight: Option<f32>,
    /// Score of the automatic match (informational, written by `--save`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub score: Option<f32>,
}

/// A whole mapping file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MappingFile {
    /// Format version.
    pub version: u32,
    /// Target bone name → how it is driven.
    #[serde(default)]
    pub bones: BTreeMap<String, FileBone>,
}

/// Parses a mapping file.
pub fn parse_mapping_file(text: &str) -> Result<MappingFile, MappingFileError> {
    let file: MappingFile = toml::from_str(text).map_err(|e| MappingFileError::Parse {
        message: e.to_string(),
    })?;
    if file.version != MAPPING_FILE_VERSION {
        return Err(MappingFileError::Version {
            found: file.version,
            expected: MAPPING_FILE_VERSION,
        });
    }
    Ok(file)
}

/// Writes a complete table as a mapping file (every target bone listed, unmapped ones with
/// `unmapped = true`).
pub fn to_mapping_file(
    table: &MappingTable,
    sources: &[&Skeleton],
    target: &Skeleton,
) -> MappingFile {
    let mut bones = BTreeMap::new();
    for t in target.bone_ids() {
        let mut fb = FileBone::default();
        match table.get(t) {
            None => fb.unmapped = true,
            Some(e) => {
                let named: Vec<FileSource> = e
                    .sources
                    .iter()
                    .filter_map(|s| {
                        let sk = sources.get(s.input as usize)?;
                        (s.bone.index() < sk.num_bones()).then(|| FileSource {
                            bone: sk.name(s.bone).to_string(),
                            input: s.input,
                            weight: s.weight,
                        })
                    })
                    .collect();
                if named.len() == 1 && named[0].input == 0 && named[0].weight == 1.0 {
                    fb.source = Some(named[0].bone.clone());
                } else {
                    fb.sources = named;
                }
                let d = BoneOptions::default();
                if e.options.delay_secs != d.delay_secs {
                    fb.delay_secs = Some(e.options.delay_secs);
                }
                if e.options.reverse != d.reverse {
                    fb.reverse = Some(e.options.reverse);
                }
                if e.options.weight != d.weight {
                    fb.weight = Some(e.options.weight);
                }
                fb.score = Some((e.score * 10.0).round() / 10.0);
            }
        }
        bones.insert(target.name(t).to_string(), fb);
    }
    MappingFile {
        version: MAPPING_FILE_VERSION,
        bones,
    }
}

/// TOML text of a mapping file.
pub fn mapping_file_to_string(file: &MappingFile) -> String {
    let body = toml::to_string_pretty(file).unwrap_or_default();
    format!("# rigcast mapping file (see retarget/MAPPING.md)\n{body}")
}

/// Merges a (partial) file over `table`: bones named in the file get exactly what it says
/// (sources replaced if given; options replaced if given; `unmapped` clears), others keep the
/// automatic result. Fails without modifying `table` when a name is unknown or the table does not
/// fit the target skeleton.
pub fn apply_overrides(
    table: &mut MappingTable,
    file: &MappingFile,
    sources: &[&Skeleton],
    target: &Skeleton,
) -> Result<(), MappingFileError> {
    if table.entries.len() != target.num_bones() {
        return Err(MappingFileError::TableSize {
            entries: table.entries.len(),
            bones: target.num_bones(),
        });
    }
    let mut out = table.clone();
    for (tname, fb) in &file.bones {
        let t = target
            .bone(tname)
            .ok_or_else(|| MappingFileError::UnknownTargetBone {
                name: tname.clone(),
            })?;
        // The person has decided this bone: nothing left to check.
        out.flagged.retain(|f| f.bone != t);
        if fb.unmapped {
            out.entries[t.index()] = None;
            continue;
        }
        let refs = source_refs(tname, fb, sources)?;
        let existing = out.entries[t.index()].take();
        let Some(mut entry) = overridden_entry(existing, refs) else {
            // Options for a bone with no source: nothing to drive.
            continue;
        };
        override_options(&mut entry.options, tname, fb)?;
        out.entries[t.index()] = Some(entry);
    }
    *table = out;
    Ok(())
}

/// The sources a file's bone `tname` lists (`source` first, then `sources`), found in the
/// source skeletons, with their weights checked.
fn source_refs(
    tname: &str,
    fb: &FileBone,
    sources: &[&Skeleton],
) -> Result<Vec<SourceRef>, MappingFileError> {
    let shorthand = fb.source.iter().map(|bone| FileSource {
        bone: bone.clone(),
        input: 0,
        weight: 1.0,
    });
    let listed: Vec<FileSource> = shorthand.chain(fb.sources.iter().cloned()).collect();
    let mut refs = Vec::with_capacity(listed.len());
    for s in &listed {
        let unknown = || MappingFileError::UnknownSourceBone {
            target: tname.to_string(),
            name: s.bone.clone(),
            input: s.input,
        };
        let sk = sources.get(s.input as usize).ok_or_else(unknown)?;
        let bone = sk.bone(&s.bone).ok_or_else(unknown)?;
        if !(s.weight.is_finite() && s.weight >= 0.0) {
            return Err(MappingFileError::BadValue {
                target: tname.to_string(),
                what: format!("weight {} must be a finite number >= 0", s.weight),
            });
        }
        refs.push(SourceRef {
            input: s.input,
            bone,
            weight: s.weight,
        });
    }
    Ok(refs)
}

/// A target bone's entry after a file names sources for it (`refs`, maybe none): the sources
/// replace the automatic ones as a certain override, keeping the bone's options; with none the
/// automatic entry stays (`None`: nothing to drive).
fn overridden_entry(existing: Option<TargetEntry>, refs: Vec<SourceRef>) -> Option<TargetEntry> {
    if refs.is_empty() {
        return existing;
    }
    Some(TargetEntry {
        sources: refs,
        options: existing.map(|e| e.options).unwrap_or_default(),
        score: 0.0,
        evidence: vec!["override".into()],
        confidence: 1.0,
    })
}

/// The per-bone options a file's bone `tname` sets, checked, over `options`.
fn override_options(
    options: &mut BoneOptions,
    tname: &str,
    fb: &FileBone,
) -> Result<(), MappingFileError> {
    let bad = |what: String| MappingFileError::BadValue {
        target: tname.to_string(),
        what,
    };
    if let Some(d) = fb.delay_secs {
        if !(d.is_finite() && d >= 0.0) {
            return Err(bad(format!("delay_secs {d} must be a finite number >= 0")));
        }
        options.delay_secs = d;
    }
    if let Some(r) = fb.reverse {
        options.reverse = r;
    }
    if let Some(w) = fb.weight {
        if !(w.is_finite() && (0.0..=1.0).contains(&w)) {
            return Err(bad(format!("weight {w} must be within 0..=1")));
        }
        options.weight = w;
    }
    Ok(())
}
