//! `VmcDecoder`: OSC datagrams → a pose on the sender's learnt skeleton. Pure: no IO, no clock.
//!
//! Per datagram: a structural check (sizes, bundle nesting) that rosc's parser does not do,
//! then rosc decodes it; a reorder check on the sender's time (`/VMC/Ext/T`) and bundle
//! timetag; then each message is applied through the [`OscMapping`] rules into fixed per-bone
//! arrays (indexed by `HumanBodyBones`). A frame is complete as soon as every bone of the
//! learnt skeleton was updated; otherwise when a `frame_end` message arrives (VMC:
//! `/VMC/Ext/T`, which senders put after the bones or before them: either way it closes what
//! came before it), or when a bone is about to be updated a second time (a sender without
//! frame markers started its next frame).
//!
//! The skeleton is learnt from the bones the sender sends and their local offsets
//! (`Bone/Pos` positions are local offsets from the parent) and rebuilt when the sender
//! starts sending another bone or other offsets (another avatar was loaded).

use std::sync::Arc;

use glam::{Quat, Vec3};
use rigcast_protocol::coords::{internal_from_unity_position, internal_from_unity_rotation};
use rigcast_retarget::{BoneId, Pose, Skeleton};
use rosc::{OscMessage, OscPacket, OscType};

use super::mapping::{BoneTarget, CompiledRule, CoordSpace, OscMapping};
use crate::error::SourceError;
use crate::live::humanoid::{build_humanoid, default_offsets, NUM_HUMAN_BONES};

use rigcast_protocol::vmc::MAX_BUNDLE_DEPTH;

/// Counters of what the decoder saw.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct VmcStats {
    /// Datagrams fed.
    pub datagrams: u64,
    /// Datagrams that were not valid OSC (dropped whole).
    pub malformed_datagrams: u64,
    /// Datagrams older than one already applied (dropped whole).
    pub reordered_datagrams: u64,
    /// Messages with too few arguments, wrong types, non-finite values or unknown bones.
    pub dropped_messages: u64,
    /// Messages whose address no rule handles (ignored, as the VMC spec asks).
    pub ignored_messages: u64,
    /// Messages applied.
    pub applied_messages: u64,
    /// Frames completed.
    pub frames: u64,
    /// Skeleton (re)builds.
    pub skeleton_builds: u64,
}

impl VmcStats {
    /// Everything dropped: malformed + reordered datagrams + dropped messages.
    pub fn dropped(&self) -> u64 {
        self.malformed_datagrams + self.reordered_datagrams + self.dropped_messages
    }
}

/// Result of feeding one datagram.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FeedResult {
    /// A frame is complete: read it with [`VmcDecoder::pose`].
    pub frame_ready: bool,
    /// The skeleton changed with this frame.
    pub skeleton_changed: bool,
    /// At least one message was applied (the sender is alive and making sense).
    pub good_input: bool,
    /// Units dropped from this datagram (1 for a malformed/reordered datagram, else the number
    /// of dropped messages).
    pub dropped: u64,
}

/// An offset change larger than this means the sender switched avatars: relearn.
const OFFSET_CHANGE_METRES: f32 = 0.005;
/// A sender time going back by more than this is a restart, not a reordered datagram.
const RESTART_BACKSTEP_SECS: f32 = 1.0;

/// Decodes VMC (or mapped OSC) datagrams into poses.
#[derive(Debug)]
pub struct VmcDecoder {
    mapping: OscMapping,
    rules: Vec<CompiledRule>,
    rotations: [Quat; NUM_HUMAN_BONES],
    positions: [Vec3; NUM_HUMAN_BONES],
    has_position: [bool; NUM_HUMAN_BONES],
    seen: [bool; NUM_HUMAN_BONES],
    dirty: [bool; NUM_HUMAN_BONES],
    root_position: Vec3,
    root_rotation: Quat,
    root_dirty: bool,
    in_skeleton: [bool; NUM_HUMAN_BONES],
    bone_of: [Option<BoneId>; NUM_HUMAN_BONES],
    num_skeleton_bones: usize,
    num_dirty: usize,
    num_dirty_in_skeleton: usize,
    relearn: bool,
    skeleton: Option<Arc<Skeleton>>,
    pose: Pose,
    last_time: Option<f32>,
    last_timetag: Option<(u32, u32)>,
    blend: Vec<(String, f32)>,
    stats: VmcStats,
}

/// Outcome of one message.
enum Applied {
    Transform,
    FrameEnd,
    Other,
    Ignored,
    Dropped,
}

impl VmcDecoder {
    /// A decoder for `mapping` (use [`OscMapping::vmc`] for VMC).
    pub fn new(mapping: OscMapping) -> Result<VmcDecoder, SourceError> {
        let rules = mapping.compile()?;
        Ok(VmcDecoder {
            mapping,
            rules,
            rotations: [Quat::IDENTITY; NUM_HUMAN_BONES],
            positions: [Vec3::ZERO; NUM_HUMAN_BONES],
            has_position: [false; NUM_HUMAN_BONES],
            seen: [false; NUM_HUMAN_BONES],
            dirty: [false; NUM_HUMAN_BONES],
            root_position: Vec3::ZERO,
            root_rotation: Quat::IDENTITY,
            root_dirty: false,
            in_skeleton: [false; NUM_HUMAN_BONES],
            bone_of: [None; NUM_HUMAN_BONES],
            num_skeleton_bones: 0,
            num_dirty: 0,
            num_dirty_in_skeleton: 0,
            relearn: false,
            skeleton: None,
            pose: Pose {
                rotations: Vec::new(),
                translations: Vec::new(),
            },
            last_time: None,
            last_timetag: None,
            blend: Vec::new(),
            stats: VmcStats::default(),
        })
    }

    /// The learnt skeleton, once the first frame completed.
    pub fn skeleton(&self) -> Option<&Arc<Skeleton>> {
        self.skeleton.as_ref()
    }

    /// The pose of the last completed frame (empty before the first).
    pub fn pose(&self) -> &Pose {
        &self.pose
    }

    /// Counters.
    pub fn stats(&self) -> VmcStats {
        self.stats
    }

    /// Latest blend shape values (`/VMC/Ext/Blend/Val`).
    pub fn blend_values(&self) -> &[(String, f32)] {
        &self.blend
    }

    /// Forgets the sender's clock (after a silence the sender may have restarted).
    pub fn reset_sequence(&mut self) {
        self.last_time = None;
        self.last_timetag = None;
    }

    /// Feeds one datagram. Never panics; bad input is counted and dropped.
    pub fn feed(&mut self, datagram: &[u8]) -> FeedResult {
        self.stats.datagrams += 1;
        let mut result = FeedResult::default();
        let packet = match rigcast_protocol::vmc::check_osc_framing(datagram)
            .ok()
            .and_then(|()| rosc::decoder::decode_udp(datagram).ok())
        {
            Some(([], packet)) => packet,
            _ => {
                self.stats.malformed_datagrams += 1;
                result.dropped = 1;
                return result;
            }
        };
        if self.is_reordered(&packet) {
            self.stats.reordered_datagrams += 1;
            result.dropped = 1;
            return result;
        }
        let dropped_before = self.stats.dropped_messages;
        self.apply_packet(&packet, &mut result);
        result.dropped = self.stats.dropped_messages - dropped_before;
        result
    }

    fn is_reordered(&mut self, packet: &OscPacket) -> bool {
        if let OscPacket::Bundle(b) = packet {
            let tag = (b.timetag.seconds, b.timetag.fractional);
            // (0, 1) means "immediately": carries no order.
            if tag != (0, 1) {
                if let Some(last) = self.last_timetag {
                    if tag < last {
                        return true;
                    }
                }
                self.last_timetag = Some(tag);
            }
        }
        if let Some(t) = self.find_time(packet, 0) {
            if let Some(last) = self.last_time {
                if t < last && last - t < RESTART_BACKSTEP_SECS {
                    return true;
                }
            }
            self.last_time = Some(t);
        }
        false
    }

    fn find_time(&self, packet: &OscPacket, depth: usize) -> Option<f32> {
        match packet {
            OscPacket::Message(m) => {
                let rule = self.rules.iter().find(|r| r.matches(&m.addr).is_some())?;
                match m.args.get(rule.time_arg?) {
                    Some(OscType::Float(t)) if t.is_finite() => Some(*t),
                    _ => None,
                }
            }
            OscPacket::Bundle(b) if depth < MAX_BUNDLE_DEPTH => {
                b.content.iter().find_map(|p| self.find_time(p, depth + 1))
            }
            OscPacket::Bundle(_) => None,
        }
    }

    fn apply_packet(&mut self, packet: &OscPacket, result: &mut FeedResult) {
        match packet {
            OscPacket::Message(m) => match self.apply_message(m, result) {
                Applied::Transform | Applied::Other => result.good_input = true,
                Applied::FrameEnd => {
                    result.good_input = true;
                    // A frame marker closes whatever arrived before it. Senders put it after
                    // the bones (then it ends this frame) or first (then it ends the previous
                    // one); either way the closed frame is whole.
                    if self.any_dirty() {
                        self.complete_frame(result);
                    }
                }
                Applied::Ignored => self.stats.ignored_messages += 1,
                Applied::Dropped => self.stats.dropped_messages += 1,
            },
            OscPacket::Bundle(b) => {
                for p in &b.content {
                    self.apply_packet(p, result);
                }
            }
        }
    }

    fn any_dirty(&self) -> bool {
        self.root_dirty || self.num_dirty > 0
    }

    fn apply_message(&mut self, m: &OscMessage, result: &mut FeedResult) -> Applied {
        let Some((rule_index, captured)) = self
            .rules
            .iter()
            .enumerate()
            .find_map(|(i, r)| r.matches(&m.addr).map(|c| (i, c)))
        else {
            return Applied::Ignored;
        };
        let rule = &self.rules[rule_index];
        if m.args.len() < rule.min_args {
            return Applied::Dropped;
        }
        let float = |i: usize| match m.args.get(i) {
            Some(OscType::Float(v)) if v.is_finite() => Some(*v),
            _ => None,
        };
        let string = |i: usize| match m.args.get(i) {
            Some(OscType::String(s)) => Some(s.as_str()),
            _ => None,
        };
        let Some((position, rotation)) = read_transform(rule, m) else {
            return Applied::Dropped;
        };
        if let Some((n, v)) = rule.blend {
            let (Some(name), Some(value)) = (string(n), float(v)) else {
                return Applied::Dropped;
            };
            let num_blend = self.blend.len();
            match self.blend.iter_mut().find(|(k, _)| k == name) {
                Some(slot) => slot.1 = value,
                // Blend names are few and fixed per avatar: allocate once per name, capped.
                None if num_blend < 256 => self.blend.push((name.to_string(), value)),
                None => return Applied::Dropped,
            }
        }
        if position.is_none() && rotation.is_none() {
            return if rule.frame_end {
                Applied::FrameEnd
            } else {
                Applied::Other
            };
        }
        let target = if let Some(t) = rule.fixed_bone {
            Some(t)
        } else if let Some(i) = rule.bone_arg {
            match string(i) {
                Some(name) => self.mapping.resolve(name),
                None => return Applied::Dropped,
            }
        } else {
            self.mapping.resolve(captured)
        };
        let frame_end = rule.frame_end;
        let Some(target) = target else {
            return Applied::Dropped;
        };
        self.apply_transform(target, position, rotation, result);
        self.stats.applied_messages += 1;
        if frame_end {
            Applied::FrameEnd
        } else {
            Applied::Transform
        }
    }

    /// Writes one message's transform onto the root or a human bone; a bone updated twice
    /// means the sender started its next frame, which completes the current one first.
    fn apply_transform(
        &mut self,
        target: BoneTarget,
        position: Option<Vec3>,
        rotation: Option<Quat>,
        result: &mut FeedResult,
    ) {
        match target {
            BoneTarget::Root => {
                if self.root_dirty {
                    // Updated twice: the sender started its next frame.
                    self.complete_frame(result);
                }
                if let Some(p) = position {
                    self.root_position = p;
                }
                if let Some(q) = rotation {
                    self.root_rotation = q;
                }
                self.root_dirty = true;
            }
            BoneTarget::Human(h) => {
                if self.dirty[h] {
                    self.complete_frame(result);
                }
                self.apply_bone(h, position, rotation);
                let all_updated = self.skeleton.is_some()
                    && !self.relearn
                    && self.num_dirty_in_skeleton == self.num_skeleton_bones;
                if all_updated {
                    self.complete_frame(result);
                }
            }
        }
    }

    fn apply_bone(&mut self, h: usize, position: Option<Vec3>, rotation: Option<Quat>) {
        if let Some(q) = rotation {
            self.rotations[h] = q;
        }
        if let Some(p) = position {
            // The hips' position is root motion; every other bone's is its rest offset.
            if h != 0
                && self.in_skeleton[h]
                && self.has_position[h]
                && (p - self.positions[h]).length() > OFFSET_CHANGE_METRES
            {
                self.relearn = true;
            }
            if h == 0 || !self.in_skeleton[h] || !self.has_position[h] || self.relearn {
                self.positions[h] = p;
            }
            self.has_position[h] = true;
        }
        if !self.seen[h] {
            self.seen[h] = true;
            if self.skeleton.is_some() {
                self.relearn = true;
            }
        }
        if !self.dirty[h] {
            self.dirty[h] = true;
            self.num_dirty += 1;
            if self.in_skeleton[h] {
                self.num_dirty_in_skeleton += 1;
            }
        }
    }

    /// Builds the skeleton if needed and writes the frame into `self.pose`.
    fn complete_frame(&mut self, result: &mut FeedResult) {
        if self.skeleton.is_none() || self.relearn {
            if !self.seen[0] {
                // Without Hips there is no humanoid yet; keep collecting.
                self.clear_dirty();
                return;
            }
            let mut offsets = default_offsets();
            for ((offset, &has), &position) in offsets
                .iter_mut()
                .zip(&self.has_position)
                .zip(&self.positions)
            {
                if has {
                    *offset = position;
                }
            }
            match build_humanoid(&self.seen, &offsets) {
                Ok(s) => {
                    self.in_skeleton = self.seen;
                    self.num_skeleton_bones = s.num_bones();
                    for h in 0..NUM_HUMAN_BONES {
                        self.bone_of[h] = if self.seen[h] {
                            s.bone(crate::live::humanoid::HUMAN_BONES[h].name)
                        } else {
                            None
                        };
                    }
                    self.pose = s.rest_pose();
                    self.skeleton = Some(Arc::new(s));
                    self.relearn = false;
                    self.stats.skeleton_builds += 1;
                    result.skeleton_changed = true;
                }
                Err(_) => {
                    self.clear_dirty();
                    return;
                }
            }
        }
        for h in 0..NUM_HUMAN_BONES {
            if let Some(id) = self.bone_of[h] {
                self.pose.rotations[id.index()] = self.rotations[h];
            }
        }
        if let Some(hips) = self.bone_of[0] {
            // Fold the root transform into the hips so the skeleton is a plain humanoid.
            let i = hips.index();
            self.pose.rotations[i] = (self.root_rotation * self.rotations[0]).normalize();
            self.pose.translations[i] = self.root_position + self.root_rotation * self.positions[0];
        }
        self.clear_dirty();
        self.stats.frames += 1;
        result.frame_ready = true;
    }

    fn clear_dirty(&mut self) {
        self.dirty = [false; NUM_HUMAN_BONES];
        self.num_dirty = 0;
        self.num_dirty_in_skeleton = 0;
        self.root_dirty = false;
    }
}

/// The time, position and rotation arguments `rule` reads from `m`, checked (finite floats,
/// a rotation of sane length, normalised) and in internal coordinates; `None` when any is
/// missing or wrong (the message is dropped).
fn read_transform(rule: &CompiledRule, m: &OscMessage) -> Option<(Option<Vec3>, Option<Quat>)> {
    let float = |i: usize| match m.args.get(i) {
        Some(OscType::Float(v)) if v.is_finite() => Some(*v),
        _ => None,
    };
    if let Some(i) = rule.time_arg {
        float(i)?;
    }
    let position = match rule.position {
        Some([x, y, z]) => Some(Vec3::new(float(x)?, float(y)?, float(z)?)),
        None => None,
    };
    let rotation = match rule.rotation {
        Some([x, y, z, w]) => {
            let q = Quat::from_xyzw(float(x)?, float(y)?, float(z)?, float(w)?);
            // A zero or wildly unnormalised quaternion is not a rotation.
            let len = q.length();
            if !(0.5..=2.0).contains(&len) {
                return None;
            }
            Some(q / len)
        }
        None => None,
    };
    Some(match rule.space {
        CoordSpace::Unity => (
            position.map(internal_from_unity_position),
            rotation.map(internal_from_unity_rotation),
        ),
        CoordSpace::Internal => (position, rotation),
    })
}
