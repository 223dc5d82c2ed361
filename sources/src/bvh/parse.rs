//! BVH reader: a small hand-written parser that reports the line of every error.
//!
//! Grammar accepted (whitespace-insensitive, CRLF or LF, tabs or spaces):
//!
//! ```text
//! HIERARCHY
//! ROOT <name> { OFFSET x y z  CHANNELS n <channel>×n  (JOINT … | End Site { OFFSET x y z })* }
//! (more ROOTs allowed)
//! MOTION
//! Frames: <n>
//! Frame Time: <seconds>
//! <one line of values per frame, in hierarchy channel order>
//! ```
//!
//! Channels may appear in any count and order per joint; rotation channels compose in the listed
//! order (BVH's intrinsic convention), position channels replace the matching offset component.
//! The rest pose is the OFFSET layout with identity rotations — which for some files is not a
//! posture at all (every bone along one axis), so nothing here assumes rest = T-pose.

use std::collections::HashSet;
use std::sync::Arc;

use glam::{Quat, Vec3};
use rigcast_retarget::{Clip, Pose, RawSkeleton, Skeleton, Transform};

use super::layout::{BvhLayout, LayoutJoint};
use super::units::{guess_unit, UnitGuess};
use super::Channel;
use crate::error::SourceError;
use crate::stature::stature;

/// Options for reading BVH.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BvhReadOptions {
    /// Metres per file unit. `None` guesses from the figure's standing height (see [`guess_unit`]).
    pub scale: Option<f32>,
}

/// A decoded BVH file.
#[derive(Debug, Clone)]
pub struct BvhRead {
    /// Skeleton (joints plus `<parent>_end` leaves for End Sites) and frames, in metres.
    pub clip: Clip,
    /// Metres per file unit that was applied.
    pub scale: f32,
    /// True when `scale` was guessed rather than given.
    pub scale_guessed: bool,
    /// 0..1, how clearly the guessed unit beats the others (see [`UnitGuess`]); 1 when given,
    /// 0 when the figure reads as no two-legged body (its height is then no evidence).
    pub scale_confidence: f32,
    /// Number of ROOT/JOINT entries (End Sites excluded).
    pub num_joints: usize,
    /// Number of End Sites (each became a leaf bone).
    pub num_end_sites: usize,
    /// Channels of each bone, indexed by the skeleton's bone ids (empty for End Sites).
    pub channels: Vec<Vec<Channel>>,
    /// The file's hierarchy exactly as written (joint order, End Sites, channels, offsets), so
    /// motion written onto this rig keeps it (see [`super::write_bvh_onto`]).
    pub layout: BvhLayout,
}

#[derive(Debug)]
struct RawJoint {
    name: String,
    parent: Option<usize>,
    offset: Vec3,
    channels: Vec<Channel>,
    is_end_site: bool,
}

#[derive(Debug, Clone, Copy)]
struct Tok<'a> {
    text: &'a str,
    line: usize,
}

struct Tokens<'a> {
    toks: Vec<Tok<'a>>,
    pos: usize,
    last_line: usize,
}

impl<'a> Tokens<'a> {
    fn peek(&self) -> Option<Tok<'a>> {
        self.toks.get(self.pos).copied()
    }

    fn next(&mut self, expected: &str) -> Result<Tok<'a>, SourceError> {
        let t = self.peek().ok_or_else(|| SourceError::UnexpectedEof {
            line: self.last_line,
            expected: expected.to_string(),
        })?;
        self.pos += 1;
        Ok(t)
    }

    fn expect(&mut self, word: &str) -> Result<Tok<'a>, SourceError> {
        let t = self.next(&format!("{word:?}"))?;
        if t.text.eq_ignore_ascii_case(word) {
            Ok(t)
        } else {
            Err(SourceError::Syntax {
                line: t.line,
                expected: format!("{word:?}"),
                found: t.text.to_string(),
            })
        }
    }

    /// Remaining tokens on `line`, consumed.
    fn rest_of_line(&mut self, line: usize) -> Vec<Tok<'a>> {
        let mut out = Vec::new();
        while let Some(t) = self.peek() {
            if t.line != line {
                break;
            }
            out.push(t);
            self.pos += 1;
        }
        out
    }

    fn number(&mut self, what: &str) -> Result<f32, SourceError> {
        let t = self.next(what)?;
        parse_number(t.text, t.line)
    }
}

/// Deepest joint nesting read (real rigs are tens of joints deep; the parser keeps its own
/// stack, so this bounds memory and FK depth, not the thread's stack).
pub const MAX_JOINT_DEPTH: usize = 1024;

/// Longest and shortest frame time accepted, seconds: frames further apart than a second are
/// not motion capture, and a replay or a resample at the output rate must stay bounded.
pub const FRAME_TIME_RANGE_SECS: (f64, f64) = (1e-5, 1.0);

fn parse_number(text: &str, line: usize) -> Result<f32, SourceError> {
    // Checked after the conversion: 1e300 is a finite f64 but an infinite f32.
    match text.parse::<f64>().map(|v| v as f32) {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(SourceError::BadNumber {
            line,
            token: text.to_string(),
        }),
    }
}

/// Parses a BVH file from bytes. `name` becomes the clip name.
pub fn read_bvh(bytes: &[u8], name: &str, opts: &BvhReadOptions) -> Result<BvhRead, SourceError> {
    let text = std::str::from_utf8(bytes).map_err(|e| SourceError::NotUtf8 {
        offset: e.valid_up_to(),
    })?;
    // `lines()` strips "\n" and "\r\n"; numbering is 1-based.
    let lines: Vec<&str> = text.lines().collect();
    let motion_at = lines
        .iter()
        .position(|l| l.split_whitespace().next() == Some("MOTION"));
    let hierarchy_end = motion_at.unwrap_or(lines.len());
    let mut toks = Vec::new();
    for (i, l) in lines[..hierarchy_end].iter().enumerate() {
        toks.extend(l.split_whitespace().map(|text| Tok { text, line: i + 1 }));
    }
    let mut tokens = Tokens {
        toks,
        pos: 0,
        last_line: hierarchy_end.max(1),
    };
    tokens.expect("HIERARCHY")?;
    let mut joints: Vec<RawJoint> = Vec::new();
    while let Some(t) = tokens.peek() {
        if t.text.eq_ignore_ascii_case("ROOT") {
            tokens.pos += 1;
            parse_tree(&mut tokens, &mut joints, t.line)?;
        } else {
            return Err(SourceError::Syntax {
                line: t.line,
                expected: "ROOT or MOTION".into(),
                found: t.text.into(),
            });
        }
    }
    if joints.is_empty() {
        return Err(SourceError::Syntax {
            line: tokens.last_line,
            expected: "at least one ROOT".into(),
            found: "MOTION".into(),
        });
    }
    let Some(motion_at) = motion_at else {
        return Err(SourceError::MissingMotion { line: lines.len() });
    };
    let (frame_time, frames) = parse_motion(&lines, motion_at, &joints)?;
    build(name, joints, frame_time, &frames, opts)
}

/// Reads one joint's header (name, `{`) after its ROOT or JOINT keyword and adds it.
fn open_joint(
    tokens: &mut Tokens<'_>,
    joints: &mut Vec<RawJoint>,
    parent: Option<usize>,
    keyword_line: usize,
) -> Result<usize, SourceError> {
    if joints.len() >= rigcast_retarget::skeleton::MAX_BONES {
        return Err(SourceError::limit(
            format!("line {keyword_line}: joint count"),
            joints.len() + 1,
            rigcast_retarget::skeleton::MAX_BONES,
        ));
    }
    // The name is the rest of the keyword's line (names may contain spaces); a trailing "{" on
    // the same line opens the block.
    let mut name_toks = tokens.rest_of_line(keyword_line);
    let mut brace_open = false;
    if name_toks.last().map(|t| t.text) == Some("{") {
        name_toks.pop();
        brace_open = true;
    }
    if name_toks.is_empty() {
        return Err(SourceError::Syntax {
            line: keyword_line,
            expected: "a joint name".into(),
            found: "end of line".into(),
        });
    }
    let name = name_toks
        .iter()
        .map(|t| t.text)
        .collect::<Vec<_>>()
        .join(" ");
    if !brace_open {
        tokens.expect("{")?;
    }
    joints.push(RawJoint {
        name,
        parent,
        offset: Vec3::ZERO,
        channels: Vec::new(),
        is_end_site: false,
    });
    Ok(joints.len() - 1)
}

/// Reads one ROOT's tree. Iterative, with its own stack of open joints (index, OFFSET seen),
/// so nesting depth is bounded by [`MAX_JOINT_DEPTH`], not by the thread's stack.
fn parse_tree(
    tokens: &mut Tokens<'_>,
    joints: &mut Vec<RawJoint>,
    keyword_line: usize,
) -> Result<(), SourceError> {
    let root = open_joint(tokens, joints, None, keyword_line)?;
    let mut open: Vec<(usize, bool)> = vec![(root, false)];
    while let Some(&(index, has_offset)) = open.last() {
        let t = tokens.next("OFFSET, CHANNELS, JOINT, End Site or \"}\"")?;
        match t.text {
            "}" => {
                if !has_offset {
                    return Err(SourceError::Syntax {
                        line: t.line,
                        expected: format!("an OFFSET for joint {:?}", joints[index].name),
                        found: "none".into(),
                    });
                }
                open.pop();
            }
            w if w.eq_ignore_ascii_case("OFFSET") => {
                joints[index].offset = read_offset(tokens)?;
                if let Some(top) = open.last_mut() {
                    top.1 = true;
                }
            }
            w if w.eq_ignore_ascii_case("CHANNELS") => {
                joints[index].channels = read_channels(tokens, t.line)?;
            }
            w if w.eq_ignore_ascii_case("JOINT") => {
                if open.len() >= MAX_JOINT_DEPTH {
                    return Err(SourceError::limit(
                        format!("line {}: joint depth", t.line),
                        open.len() + 1,
                        MAX_JOINT_DEPTH,
                    ));
                }
                let child = open_joint(tokens, joints, Some(index), t.line)?;
                open.push((child, false));
            }
            w if w.eq_ignore_ascii_case("End") => {
                tokens.expect("Site")?;
                tokens.expect("{")?;
                tokens.expect("OFFSET")?;
                let offset = read_offset(tokens)?;
                tokens.expect("}")?;
                let end_name = format!("{}_end", joints[index].name);
                joints.push(RawJoint {
                    name: end_name,
                    parent: Some(index),
                    offset,
                    channels: Vec::new(),
                    is_end_site: true,
                });
            }
            other => {
                return Err(SourceError::Syntax {
                    line: t.line,
                    expected: "OFFSET, CHANNELS, JOINT, End Site or \"}\"".into(),
                    found: other.into(),
                })
            }
        }
    }
    Ok(())
}

fn read_offset(tokens: &mut Tokens<'_>) -> Result<Vec3, SourceError> {
    Ok(Vec3::new(
        tokens.number("offset x")?,
        tokens.number("offset y")?,
        tokens.number("offset z")?,
    ))
}

fn read_channels(tokens: &mut Tokens<'_>, line: usize) -> Result<Vec<Channel>, SourceError> {
    let count_tok = tokens.next("a channel count")?;
    let declared: usize = count_tok.text.parse().map_err(|_| SourceError::BadNumber {
        line: count_tok.line,
        token: count_tok.text.into(),
    })?;
    // Channel names sit on the CHANNELS line; counting them there catches a wrong count before
    // it silently eats the next keyword.
    let names = tokens.rest_of_line(line);
    if names.len() != declared {
        return Err(SourceError::ChannelCount {
            line,
            declared,
            found: names.len(),
        });
    }
    names
        .iter()
        .map(|t| {
            Channel::from_name(t.text).ok_or_else(|| SourceError::UnknownChannel {
                line: t.line,
                name: t.text.into(),
            })
        })
        .collect()
}

/// Returns the frame time and the raw channel values of every frame.
fn parse_motion(
    lines: &[&str],
    motion_at: usize,
    joints: &[RawJoint],
) -> Result<(f64, Vec<Vec<f32>>), SourceError> {
    let num_channels: usize = joints.iter().map(|j| j.channels.len()).sum();
    let mut i = motion_at + 1;
    let (at, count) = header_entry(lines, &mut i, "Frames:", "\"Frames: <count>\"")?;
    let declared = count.parse::<usize>().map_err(|_| SourceError::BadNumber {
        line: at + 1,
        token: count.into(),
    })?;
    let (at, time) = header_entry(lines, &mut i, "Frame Time:", "\"Frame Time: <seconds>\"")?;
    let frame_time = frame_time(time, at)?;
    let frames = frame_rows(&lines[i..], i, num_channels, declared)?;
    Ok((frame_time, frames))
}

/// The next non-blank line from `i` (moved past it), which must start with `label`: its line
/// index and the trimmed value after the label. `expected` names the entry in errors.
fn header_entry<'a>(
    lines: &[&'a str],
    i: &mut usize,
    label: &str,
    expected: &str,
) -> Result<(usize, &'a str), SourceError> {
    // Skip blank lines between header entries.
    while *i < lines.len() && lines[*i].trim().is_empty() {
        *i += 1;
    }
    let Some(line) = lines.get(*i).map(|l| l.trim()) else {
        return Err(SourceError::UnexpectedEof {
            line: lines.len(),
            expected: expected.into(),
        });
    };
    let at = *i;
    *i += 1;
    match line.strip_prefix(label) {
        Some(v) => Ok((at, v.trim())),
        None => Err(SourceError::Syntax {
            line: at + 1,
            expected: expected.into(),
            found: line.into(),
        }),
    }
}

/// The frame time `value` (on line index `at`): positive, finite and within
/// [`FRAME_TIME_RANGE_SECS`].
fn frame_time(value: &str, at: usize) -> Result<f64, SourceError> {
    match value.parse::<f64>() {
        Ok(t) if t.is_finite() && t > 0.0 => {
            let (shortest, longest) = FRAME_TIME_RANGE_SECS;
            if !(shortest..=longest).contains(&t) {
                return Err(SourceError::limit(
                    format!("line {}: Frame Time", at + 1),
                    value,
                    format!("{shortest}..={longest} s"),
                ));
            }
            Ok(t)
        }
        _ => Err(SourceError::BadNumber {
            line: at + 1,
            token: value.into(),
        }),
    }
}

/// The frames' channel values: one row of `num_channels` numbers per non-blank line of `rows`
/// (which start at line index `first`), `declared` rows in all.
fn frame_rows(
    rows: &[&str],
    first: usize,
    num_channels: usize,
    declared: usize,
) -> Result<Vec<Vec<f32>>, SourceError> {
    // Cap the up-front reservation: the declared count is untrusted.
    let mut frames = Vec::with_capacity(declared.min(rows.len()));
    for (k, l) in rows.iter().enumerate() {
        if l.trim().is_empty() {
            continue;
        }
        let line = first + k + 1;
        let mut values = Vec::with_capacity(num_channels);
        for tok in l.split_whitespace() {
            values.push(parse_number(tok, line)?);
        }
        if values.len() != num_channels {
            return Err(SourceError::FrameValues {
                line,
                expected: num_channels,
                found: values.len(),
            });
        }
        frames.push(values);
    }
    if frames.len() != declared {
        return Err(SourceError::FrameCountMismatch {
            declared,
            found: frames.len(),
        });
    }
    Ok(frames)
}

/// Local rotation and translation of one joint from its channel values (file units).
fn joint_local(j: &RawJoint, values: &[f32], scale: f32) -> (Quat, Vec3) {
    let mut rotation = Quat::IDENTITY;
    let mut t = j.offset;
    for (c, &v) in j.channels.iter().zip(values) {
        match c {
            Channel::Xposition => t.x = v,
            Channel::Yposition => t.y = v,
            Channel::Zposition => t.z = v,
            Channel::Xrotation => rotation *= Quat::from_rotation_x(v.to_radians()),
            Channel::Yrotation => rotation *= Quat::from_rotation_y(v.to_radians()),
            Channel::Zrotation => rotation *= Quat::from_rotation_z(v.to_radians()),
        }
    }
    (rotation.normalize(), t * scale)
}

/// Largest bounding-box extent of the joint positions, and whether the box is degenerate
/// (all joints near one line: a rest layout that is not a posture).
pub fn extent_of(points: &[Vec3]) -> (f32, bool) {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for p in points {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    if points.is_empty() {
        return (0.0, true);
    }
    let mut e = [hi.x - lo.x, hi.y - lo.y, hi.z - lo.z];
    e.sort_by(|a, b| b.total_cmp(a));
    (e[0], e[1] < 0.05 * e[0])
}

fn positions(joints: &[RawJoint], frame: Option<&[f32]>) -> Vec<Vec3> {
    let mut world: Vec<(Quat, Vec3)> = Vec::with_capacity(joints.len());
    let mut k = 0;
    for j in joints {
        let (r, t) = match frame {
            Some(values) => {
                let n = j.channels.len();
                let out = joint_local(j, &values[k..k + n], 1.0);
                k += n;
                out
            }
            None => (Quat::IDENTITY, j.offset),
        };
        let w = match j.parent {
            Some(p) => {
                let (pr, pt) = world[p];
                (pr * r, pt + pr * t)
            }
            None => (r, t),
        };
        world.push(w);
    }
    world.into_iter().map(|(_, t)| t).collect()
}

/// A first unit from the joints' largest extent (on the first frame when the rest lies on a
/// line), close enough to size the analysis that measures the standing height.
fn provisional_scale(joints: &[RawJoint], frames: &[Vec<f32>]) -> f32 {
    let (mut size, degenerate) = extent_of(&positions(joints, None));
    if degenerate {
        if let Some(first) = frames.first() {
            size = extent_of(&positions(joints, Some(first))).0;
        }
    }
    guess_unit(size).scale
}

/// The skeleton of `joints` at `scale` metres per unit, and each joint's bone index.
fn skeleton_at(
    joints: &[RawJoint],
    scale: f32,
) -> Result<(Arc<Skeleton>, Vec<usize>), SourceError> {
    let mut raw = RawSkeleton::default();
    for j in joints {
        raw.add(
            j.name.clone(),
            j.parent,
            Transform::from_translation(j.offset * scale),
        );
    }
    let skeleton = Arc::new(Skeleton::build(&raw)?);
    // Map file order to skeleton order (identical for well-formed files, but don't rely on it).
    let mut to_bone = Vec::with_capacity(joints.len());
    for j in joints {
        let id = skeleton
            .bone(&j.name)
            .ok_or_else(|| SourceError::InvalidOption {
                reason: format!("bone {:?} vanished while building the skeleton", j.name),
            })?;
        to_bone.push(id.index());
    }
    Ok((skeleton, to_bone))
}

/// One frame's channel values as a pose of `skeleton`.
fn pose_of(
    skeleton: &Skeleton,
    joints: &[RawJoint],
    to_bone: &[usize],
    values: &[f32],
    scale: f32,
) -> Pose {
    let mut pose = Pose::from_rest(skeleton);
    let mut k = 0;
    for (ji, j) in joints.iter().enumerate() {
        let n = j.channels.len();
        let (r, t) = joint_local(j, &values[k..k + n], scale);
        k += n;
        pose.rotations[to_bone[ji]] = r;
        pose.translations[to_bone[ji]] = t;
    }
    pose
}

fn build(
    name: &str,
    mut joints: Vec<RawJoint>,
    frame_time: f64,
    frames: &[Vec<f32>],
    opts: &BvhReadOptions,
) -> Result<BvhRead, SourceError> {
    unique_end_site_names(&mut joints);
    let given = match opts.scale {
        Some(s) if s.is_finite() && s > 0.0 => Some(s),
        Some(s) => {
            return Err(SourceError::InvalidOption {
                reason: format!("BVH scale must be positive and finite, got {s}"),
            })
        }
        None => None,
    };
    let (unit, skeleton, to_bone) = match given {
        Some(scale) => {
            let (skeleton, to_bone) = skeleton_at(&joints, scale)?;
            let unit = UnitGuess {
                scale,
                confidence: 1.0,
            };
            (unit, skeleton, to_bone)
        }
        None => guessed_unit(&joints, frames)?,
    };
    let scale = unit.scale;
    let poses: Vec<Pose> = frames
        .iter()
        .map(|v| pose_of(&skeleton, &joints, &to_bone, v, scale))
        .collect();
    let mut channels = vec![Vec::new(); joints.len()];
    for (ji, j) in joints.iter().enumerate() {
        channels[to_bone[ji]] = j.channels.clone();
    }
    let num_end_sites = joints.iter().filter(|j| j.is_end_site).count();
    let layout = BvhLayout {
        joints: joints
            .iter()
            .enumerate()
            .map(|(ji, j)| LayoutJoint {
                bone: to_bone[ji],
                parent: j.parent,
                end_site: j.is_end_site,
                channels: j.channels.clone(),
                offset: j.offset,
            })
            .collect(),
        scale,
    };
    let clip = Clip::new(name, skeleton, poses, frame_time)?;
    Ok(BvhRead {
        clip,
        scale,
        scale_guessed: given.is_none(),
        scale_confidence: unit.confidence,
        num_joints: joints.len() - num_end_sites,
        num_end_sites,
        channels,
        layout,
    })
}

/// End Site names may collide with real joints: each is made unique, deterministically, by a
/// number after it (2, 3, …).
fn unique_end_site_names(joints: &mut [RawJoint]) {
    let mut used: HashSet<String> = joints
        .iter()
        .filter(|j| !j.is_end_site)
        .map(|j| j.name.clone())
        .collect();
    for j in joints.iter_mut().filter(|j| j.is_end_site) {
        let base = j.name.clone();
        let mut candidate = base.clone();
        let mut n = 2;
        while used.contains(&candidate) {
            candidate = format!("{base}{n}");
            n += 1;
        }
        used.insert(candidate.clone());
        j.name = candidate;
    }
}

/// The file's unit guessed from the figure, with the skeleton at it. A provisional unit only
/// sizes the analysis; the guess is made on the figure's standing height along its own up
/// axis.
fn guessed_unit(
    joints: &[RawJoint],
    frames: &[Vec<f32>],
) -> Result<(UnitGuess, Arc<Skeleton>, Vec<usize>), SourceError> {
    let provisional = provisional_scale(joints, frames);
    let (skeleton, to_bone) = skeleton_at(joints, provisional)?;
    let first = frames
        .first()
        .map(|v| pose_of(&skeleton, joints, &to_bone, v, provisional));
    let figure = stature(&skeleton, first.as_ref());
    let mut unit = guess_unit(figure.height / provisional);
    if !figure.two_legged {
        // The guess compares the height with a person's: for a figure that reads as no
        // two-legged body (a quadruped, a prop) that is no evidence, so say so.
        unit.confidence = 0.0;
    }
    if unit.scale == provisional {
        return Ok((unit, skeleton, to_bone));
    }
    let (skeleton, to_bone) = skeleton_at(joints, unit.scale)?;
    Ok((unit, skeleton, to_bone))
}
