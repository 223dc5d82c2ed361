//! VMC (Virtual Motion Capture protocol, OSC over UDP): encoder and decoder.
//!
//! The encoder packs one pose into OSC bundles of at most `max_bundle_bytes` (1500 by default,
//! one Ethernet MTU, so a bundle never fragments):
//!
//! ```text
//! bundle 1: /VMC/Ext/OK 1 · /VMC/Ext/T time · /VMC/Ext/Root/Pos "root" identity · Bone/Pos…
//! bundle 2…: /VMC/Ext/Bone/Pos name px py pz qx qy qz qw   (as many as fit)
//! ```
//!
//! `Bone/Pos` carries each bone's LOCAL translation and rotation converted to Unity space
//! (see [`crate::coords`]). `Root/Pos` is the avatar's placement, which rigcast leaves at the
//! origin: the root bone's motion travels in its own `Bone/Pos`. The OSC bytes are written by
//! hand into reused buffers, so steady-state encoding allocates nothing.
//!
//! The decoder ([`decode_packet`]) follows the receiver rules of the spec: unknown addresses and
//! extra arguments are ignored; a message with too few or wrongly typed arguments yields an
//! error for that message only. Decoded values stay in Unity space (what is on the wire).

use glam::{Quat, Vec3};
use rosc::{OscMessage, OscPacket, OscType};
use thiserror::Error;

use crate::coords::{unity_from_internal_position, unity_from_internal_rotation};

/// Default VMC Marionette (receiver) port.
pub const DEFAULT_MARIONETTE_PORT: u16 = 39539;
/// Default bundle size cap: one Ethernet MTU.
pub const DEFAULT_MAX_BUNDLE_BYTES: usize = 1500;

/// `/VMC/Ext/OK`
pub const ADDR_OK: &str = "/VMC/Ext/OK";
/// `/VMC/Ext/T`
pub const ADDR_TIME: &str = "/VMC/Ext/T";
/// `/VMC/Ext/Root/Pos`
pub const ADDR_ROOT_POS: &str = "/VMC/Ext/Root/Pos";
/// `/VMC/Ext/Bone/Pos`
pub const ADDR_BONE_POS: &str = "/VMC/Ext/Bone/Pos";
/// `/VMC/Ext/Blend/Val`
pub const ADDR_BLEND_VAL: &str = "/VMC/Ext/Blend/Val";
/// `/VMC/Ext/Blend/Apply`
pub const ADDR_BLEND_APPLY: &str = "/VMC/Ext/Blend/Apply";

const BUNDLE_HEADER_BYTES: usize = 16; // "#bundle\0" + 8-byte time tag
const TIMETAG_IMMEDIATELY: u64 = 1;

/// Errors from VMC decoding.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum VmcError {
    /// The bytes are not a valid OSC packet.
    #[error("malformed OSC packet ({len} bytes): {reason}")]
    Osc {
        /// packet size
        len: usize,
        /// rosc's description
        reason: String,
    },
    /// A known address with too few arguments.
    #[error("{address}: expected at least {expected} arguments, got {got}")]
    TooFewArgs {
        /// OSC address
        address: String,
        /// arguments required
        expected: usize,
        /// arguments present
        got: usize,
    },
    /// A known address with an argument of the wrong type.
    #[error("{address}: argument {index} should be {expected}, got {got}")]
    WrongType {
        /// OSC address
        address: String,
        /// zero-based argument index
        index: usize,
        /// expected OSC type
        expected: &'static str,
        /// type found
        got: String,
    },
}

/// A decoded VMC message (values in Unity space, as on the wire).
#[derive(Debug, Clone, PartialEq)]
pub enum VmcMessage {
    /// `/VMC/Ext/OK loaded …`
    Ok {
        /// 1 when the sender has a model loaded
        loaded: i32,
    },
    /// `/VMC/Ext/T time`
    Time {
        /// sender-relative seconds
        secs: f32,
    },
    /// `/VMC/Ext/Root/Pos name p q`
    RootPos {
        /// usually "root"
        name: String,
        /// Unity-space position
        position: Vec3,
        /// Unity-space rotation
        rotation: Quat,
    },
    /// `/VMC/Ext/Bone/Pos name p q`
    BonePos {
        /// HumanBodyBones (or any) name
        name: String,
        /// Unity-space local position
        position: Vec3,
        /// Unity-space local rotation
        rotation: Quat,
    },
    /// `/VMC/Ext/Blend/Val name value`
    BlendVal {
        /// blend shape name
        name: String,
        /// weight
        value: f32,
    },
    /// `/VMC/Ext/Blend/Apply`
    BlendApply,
}

/// One bone to encode, in internal space.
#[derive(Debug, Clone, Copy)]
pub struct VmcBone<'a> {
    /// Name sent on the wire.
    pub name: &'a str,
    /// Local translation, internal space.
    pub translation: Vec3,
    /// Local rotation, internal space.
    pub rotation: Quat,
}

/// Packs poses into size-capped VMC bundles, reusing its buffers between calls.
#[derive(Debug)]
pub struct VmcEncoder {
    max_bundle_bytes: usize,
    bundles: Vec<Vec<u8>>,
    num_bundles: usize,
    message: Vec<u8>,
    skipped: usize,
}

impl Default for VmcEncoder {
    fn default() -> Self {
        Self::new()
    }
}

impl VmcEncoder {
    /// An encoder with the default 1500-byte cap.
    pub fn new() -> Self {
        Self::with_max_bundle_bytes(DEFAULT_MAX_BUNDLE_BYTES)
    }

    /// An encoder with a custom cap (clamped to at least 256 bytes so the header messages fit).
    pub fn with_max_bundle_bytes(max_bundle_bytes: usize) -> Self {
        VmcEncoder {
            max_bundle_bytes: max_bundle_bytes.max(256),
            bundles: Vec::new(),
            num_bundles: 0,
            message: Vec::with_capacity(256),
            skipped: 0,
        }
    }

    /// Bones left out of the last [`encode`](Self::encode) because a single message would not
    /// fit in a bundle (absurdly long names).
    pub fn skipped_bones(&self) -> usize {
        self.skipped
    }

    /// Encodes one pose and returns the bundles, each ≤ the cap. `time_secs` is sent in
    /// `/VMC/Ext/T`. Allocates nothing once the buffers have grown to the pose's size.
    pub fn encode<'a>(
        &mut self,
        time_secs: f32,
        bones: impl IntoIterator<Item = VmcBone<'a>>,
    ) -> &[Vec<u8>] {
        self.num_bundles = 0;
        self.skipped = 0;
        self.start_bundle();

        self.message.clear();
        write_message(&mut self.message, ADDR_OK, |m| {
            m.types(",i");
            m.i32(1);
        });
        self.push_message();
        self.message.clear();
        write_message(&mut self.message, ADDR_TIME, |m| {
            m.types(",f");
            m.f32(time_secs);
        });
        self.push_message();
        self.message.clear();
        write_message(&mut self.message, ADDR_ROOT_POS, |m| {
            m.types(",sfffffff");
            m.str("root");
            for v in [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0] {
                m.f32(v);
            }
        });
        self.push_message();

        for bone in bones {
            let p = unity_from_internal_position(bone.translation);
            let q = unity_from_internal_rotation(bone.rotation);
            self.message.clear();
            write_message(&mut self.message, ADDR_BONE_POS, |m| {
                m.types(",sfffffff");
                m.str(bone.name);
                for v in [p.x, p.y, p.z, q.x, q.y, q.z, q.w] {
                    m.f32(v);
                }
            });
            self.push_message();
        }
        &self.bundles[..self.num_bundles]
    }

    fn start_bundle(&mut self) {
        if self.bundles.len() == self.num_bundles {
            self.bundles.push(Vec::with_capacity(self.max_bundle_bytes));
        }
        let b = &mut self.bundles[self.num_bundles];
        b.clear();
        b.extend_from_slice(b"#bundle\0");
        b.extend_from_slice(&TIMETAG_IMMEDIATELY.to_be_bytes());
        self.num_bundles += 1;
    }

    /// Appends `self.message` to the current bundle, starting a new one when it would overflow.
    fn push_message(&mut self) {
        let needed = 4 + self.message.len();
        if BUNDLE_HEADER_BYTES + needed > self.max_bundle_bytes {
            self.skipped += 1;
            return;
        }
        let current_len = self.bundles[self.num_bundles - 1].len();
        if current_len + needed > self.max_bundle_bytes {
            self.start_bundle();
        }
        let b = &mut self.bundles[self.num_bundles - 1];
        b.extend_from_slice(&(self.message.len() as i32).to_be_bytes());
        b.extend_from_slice(&self.message);
    }
}

/// Writes OSC message parts; every part is padded to 4 bytes as OSC requires.
struct MessageWriter<'a>(&'a mut Vec<u8>);

impl MessageWriter<'_> {
    fn str(&mut self, s: &str) {
        self.0.extend_from_slice(s.as_bytes());
        // At least one NUL terminator, then pad to a multiple of four.
        let pad = 4 - s.len() % 4;
        self.0.extend_from_slice(&[0u8; 4][..pad]);
    }
    fn types(&mut self, t: &str) {
        self.str(t);
    }
    fn i32(&mut self, v: i32) {
        self.0.extend_from_slice(&v.to_be_bytes());
    }
    fn f32(&mut self, v: f32) {
        self.0.extend_from_slice(&v.to_be_bytes());
    }
}

fn write_message(out: &mut Vec<u8>, address: &str, body: impl FnOnce(&mut MessageWriter)) {
    let mut w = MessageWriter(out);
    w.str(address);
    body(&mut w);
}

/// Decodes one UDP datagram (a message or a bundle, possibly nested). The outer error is for
/// bytes that are not OSC at all; each inner result is one recognised VMC message or the reason
/// it was dropped. Unknown addresses are skipped silently.
pub fn decode_packet(bytes: &[u8]) -> Result<Vec<Result<VmcMessage, VmcError>>, VmcError> {
    let osc_error = |reason: String| VmcError::Osc {
        len: bytes.len(),
        reason,
    };
    // rosc silently stops at a truncated bundle element; check the framing first so a cut
    // datagram is reported rather than half-read.
    check_framing(bytes, 0, 0).map_err(osc_error)?;
    let (rest, packet) = rosc::decoder::decode_udp(bytes).map_err(|e| osc_error(e.to_string()))?;
    if !rest.is_empty() {
        return Err(osc_error(format!("{} trailing bytes", rest.len())));
    }
    let mut out = Vec::new();
    collect(&packet, &mut out);
    Ok(out)
}

/// Bundles nest at most this deep. VMC senders do not nest at all; rosc decodes nesting by
/// recursion, so one datagram of a few thousand nested bundles would overflow the stack.
pub const MAX_BUNDLE_DEPTH: usize = 8;

/// Arrays (`[` … `]` in a message's type tags) nest at most this deep. VMC uses none; rosc
/// builds nested arrays as nested vectors, whose drop recurses once per level, so a message of
/// tens of thousands of `[` would overflow the stack when it is freed.
pub const MAX_ARRAY_DEPTH: usize = 8;

/// Checks an OSC datagram's bundle framing before it reaches a recursive decoder: every bundle's
/// size-prefixed elements exactly fill it, bundles nest at most [`MAX_BUNDLE_DEPTH`] deep and
/// each message's arrays at most [`MAX_ARRAY_DEPTH`] deep (the rest of a message is validated
/// by the decoder). Shared by every OSC input in rigcast.
pub fn check_osc_framing(datagram: &[u8]) -> Result<(), VmcError> {
    check_framing(datagram, 0, 0).map_err(|reason| VmcError::Osc {
        len: datagram.len(),
        reason,
    })
}

/// Checks that a bundle's size-prefixed elements exactly fill it and that bundles nest at most
/// [`MAX_BUNDLE_DEPTH`] deep. `base` is `bytes`' offset in the datagram (for the messages).
fn check_framing(bytes: &[u8], depth: usize, base: usize) -> Result<(), String> {
    if !bytes.starts_with(b"#bundle\0") {
        // A plain message: rosc validates the rest of it.
        return check_array_depth(bytes, base);
    }
    if depth >= MAX_BUNDLE_DEPTH {
        return Err(format!(
            "bundle at offset {base} is nested deeper than {MAX_BUNDLE_DEPTH} levels"
        ));
    }
    if bytes.len() < BUNDLE_HEADER_BYTES {
        return Err(format!(
            "bundle at offset {base} needs a {BUNDLE_HEADER_BYTES}-byte header, got {} bytes",
            bytes.len()
        ));
    }
    let mut offset = BUNDLE_HEADER_BYTES;
    while offset < bytes.len() {
        let Some(size_bytes) = bytes.get(offset..offset + 4) else {
            return Err(format!(
                "truncated element size at offset {}",
                base + offset
            ));
        };
        let size = i32::from_be_bytes([size_bytes[0], size_bytes[1], size_bytes[2], size_bytes[3]]);
        let start = offset + 4;
        let end = usize::try_from(size)
            .ok()
            .and_then(|s| start.checked_add(s))
            .filter(|&e| e <= bytes.len() && size > 0 && size % 4 == 0)
            .ok_or_else(|| {
                format!(
                    "element at offset {} declares {size} bytes, {} remain",
                    base + offset,
                    bytes.len() - start
                )
            })?;
        check_framing(&bytes[start..end], depth + 1, base + start)?;
        offset = end;
    }
    Ok(())
}

/// Checks that the arrays in a message's type tags nest at most [`MAX_ARRAY_DEPTH`] deep: one
/// pass over the tags, no recursion. A message too short to hold tags is left to the decoder.
fn check_array_depth(message: &[u8], base: usize) -> Result<(), String> {
    // The address: a NUL-terminated string padded to 4 bytes; the type tags follow.
    let Some(end) = message.iter().position(|&b| b == 0) else {
        return Ok(());
    };
    let tags_at = (end + 4) & !3;
    let tags = message.get(tags_at..).unwrap_or_default();
    let tags = tags.split(|&b| b == 0).next().unwrap_or_default();
    let mut depth = 0usize;
    for &t in tags {
        match t {
            b'[' => {
                depth += 1;
                if depth > MAX_ARRAY_DEPTH {
                    return Err(format!(
                        "message at offset {base} nests arrays deeper than {MAX_ARRAY_DEPTH} levels"
                    ));
                }
            }
            b']' => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    Ok(())
}

fn collect(packet: &OscPacket, out: &mut Vec<Result<VmcMessage, VmcError>>) {
    match packet {
        OscPacket::Message(m) => {
            if let Some(r) = decode_message(m).transpose() {
                out.push(r);
            }
        }
        OscPacket::Bundle(b) => {
            for p in &b.content {
                collect(p, out);
            }
        }
    }
}

/// Decodes one OSC message. `Ok(None)` for addresses VMC output does not use here.
pub fn decode_message(m: &OscMessage) -> Result<Option<VmcMessage>, VmcError> {
    let args = Args {
        address: &m.addr,
        args: &m.args,
    };
    let msg = match m.addr.as_str() {
        ADDR_OK => {
            args.need(1)?;
            VmcMessage::Ok {
                loaded: args.int(0)?,
            }
        }
        ADDR_TIME => {
            args.need(1)?;
            VmcMessage::Time {
                secs: args.float(0)?,
            }
        }
        ADDR_ROOT_POS | ADDR_BONE_POS => {
            args.need(8)?;
            let name = args.string(0)?.to_string();
            let position = Vec3::new(args.float(1)?, args.float(2)?, args.float(3)?);
            let rotation = Quat::from_xyzw(
                args.float(4)?,
                args.float(5)?,
                args.float(6)?,
                args.float(7)?,
            );
            if m.addr == ADDR_ROOT_POS {
                VmcMessage::RootPos {
                    name,
                    position,
                    rotation,
                }
            } else {
                VmcMessage::BonePos {
                    name,
                    position,
                    rotation,
                }
            }
        }
        ADDR_BLEND_VAL => {
            args.need(2)?;
            VmcMessage::BlendVal {
                name: args.string(0)?.to_string(),
                value: args.float(1)?,
            }
        }
        ADDR_BLEND_APPLY => VmcMessage::BlendApply,
        _ => return Ok(None),
    };
    Ok(Some(msg))
}

struct Args<'a> {
    address: &'a str,
    args: &'a [OscType],
}

impl Args<'_> {
    fn need(&self, expected: usize) -> Result<(), VmcError> {
        if self.args.len() < expected {
            return Err(VmcError::TooFewArgs {
                address: self.address.to_string(),
                expected,
                got: self.args.len(),
            });
        }
        Ok(())
    }
    fn wrong(&self, index: usize, expected: &'static str) -> VmcError {
        VmcError::WrongType {
            address: self.address.to_string(),
            index,
            expected,
            got: format!("{:?}", self.args[index]),
        }
    }
    fn float(&self, i: usize) -> Result<f32, VmcError> {
        match self.args[i] {
            OscType::Float(v) => Ok(v),
            _ => Err(self.wrong(i, "float")),
        }
    }
    fn int(&self, i: usize) -> Result<i32, VmcError> {
        match self.args[i] {
            OscType::Int(v) => Ok(v),
            _ => Err(self.wrong(i, "int")),
        }
    }
    fn string(&self, i: usize) -> Result<&str, VmcError> {
        match &self.args[i] {
            OscType::String(s) => Ok(s),
            _ => Err(self.wrong(i, "string")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::coords::{internal_from_unity_position, internal_from_unity_rotation};
    use rosc::{OscBundle, OscTime};

    fn bones(n: usize) -> (Vec<String>, Vec<Vec3>, Vec<Quat>) {
        let names = (0..n).map(|i| format!("Bone{i:02}")).collect();
        let t = (0..n)
            .map(|i| Vec3::new(i as f32 * 0.1, 0.2, -0.3 * i as f32))
            .collect();
        let r = (0..n)
            .map(|i| Quat::from_rotation_y(0.1 * i as f32) * Quat::from_rotation_x(0.05 * i as f32))
            .collect();
        (names, t, r)
    }

    fn encode_all(enc: &mut VmcEncoder, names: &[String], t: &[Vec3], r: &[Quat]) -> Vec<Vec<u8>> {
        enc.encode(
            1.5,
            names.iter().zip(t).zip(r).map(|((n, &t), &r)| VmcBone {
                name: n,
                translation: t,
                rotation: r,
            }),
        )
        .to_vec()
    }

    #[test]
    fn encodes_decodable_bundles_under_the_cap_with_all_bones() {
        let (names, t, r) = bones(65);
        let mut enc = VmcEncoder::new();
        let bundles = encode_all(&mut enc, &names, &t, &r);
        assert!(bundles.len() > 1, "65 bones cannot fit in one MTU");
        let mut got = Vec::new();
        let mut saw_ok = false;
        let mut saw_time = false;
        let mut saw_root = false;
        for b in &bundles {
            assert!(b.len() <= 1500, "bundle of {} bytes", b.len());
            // Cross-check the hand-written bytes with an independent OSC decoder.
            let (rest, packet) = rosc::decoder::decode_udp(b).unwrap();
            assert!(rest.is_empty());
            assert!(matches!(packet, OscPacket::Bundle(_)));
            for m in decode_packet(b).unwrap() {
                match m.unwrap() {
                    VmcMessage::Ok { loaded } => saw_ok = loaded == 1,
                    VmcMessage::Time { secs } => saw_time = secs == 1.5,
                    VmcMessage::RootPos { rotation, .. } => saw_root = rotation == Quat::IDENTITY,
                    VmcMessage::BonePos {
                        name,
                        position,
                        rotation,
                    } => got.push((name, position, rotation)),
                    other => panic!("unexpected {other:?}"),
                }
            }
        }
        assert!(saw_ok && saw_time && saw_root);
        assert_eq!(got.len(), 65);
        for (i, (name, p, q)) in got.iter().enumerate() {
            assert_eq!(name, &names[i]);
            assert_eq!(internal_from_unity_position(*p), t[i]);
            assert_eq!(internal_from_unity_rotation(*q), r[i]);
            // Unity space on the wire: x of positions is mirrored.
            assert_eq!(p.x, -t[i].x);
        }
    }

    #[test]
    fn respects_smaller_caps_and_reuses_buffers() {
        let (names, t, r) = bones(40);
        let mut enc = VmcEncoder::with_max_bundle_bytes(400);
        let first = encode_all(&mut enc, &names, &t, &r);
        assert!(first.iter().all(|b| b.len() <= 400));
        let ptrs: Vec<_> = enc.bundles.iter().map(|b| b.as_ptr()).collect();
        let second = encode_all(&mut enc, &names, &t, &r);
        assert_eq!(first, second);
        let again: Vec<_> = enc.bundles.iter().map(|b| b.as_ptr()).collect();
        assert_eq!(ptrs, again, "buffers are reused");
    }

    #[test]
    fn skips_bones_that_cannot_fit() {
        let long = "x".repeat(2000);
        let mut enc = VmcEncoder::new();
        let bundles = enc
            .encode(
                0.0,
                [
                    VmcBone {
                        name: &long,
                        translation: Vec3::ZERO,
                        rotation: Quat::IDENTITY,
                    },
                    VmcBone {
                        name: "Hips",
                        translation: Vec3::ZERO,
                        rotation: Quat::IDENTITY,
                    },
                ],
            )
            .to_vec();
        assert_eq!(enc.skipped_bones(), 1);
        let n: usize = bundles
            .iter()
            .map(|b| decode_packet(b).unwrap().len())
            .sum();
        assert_eq!(n, 4); // OK, T, Root, Hips
    }

    fn encode_msg(addr: &str, args: Vec<OscType>) -> Vec<u8> {
        rosc::encoder::encode(&OscPacket::Message(OscMessage {
            addr: addr.into(),
            args,
        }))
        .unwrap()
    }

    #[test]
    fn decoder_ignores_unknown_addresses_and_extra_args() {
        let bundle = OscPacket::Bundle(OscBundle {
            timetag: OscTime {
                seconds: 0,
                fractional: 1,
            },
            content: vec![
                OscPacket::Message(OscMessage {
                    addr: "/VMC/Ext/Hmd/Pos".into(),
                    args: vec![OscType::String("x".into())],
                }),
                OscPacket::Message(OscMessage {
                    addr: ADDR_ROOT_POS.into(),
                    args: [
                        vec![OscType::String("root".into())],
                        (0..13).map(|i| OscType::Float(i as f32)).collect(),
                    ]
                    .concat(),
                }),
                OscPacket::Message(OscMessage {
                    addr: ADDR_OK.into(),
                    args: vec![OscType::Int(1), OscType::Int(0), OscType::Int(2)],
                }),
                OscPacket::Message(OscMessage {
                    addr: ADDR_BLEND_VAL.into(),
                    args: vec![OscType::String("A".into()), OscType::Float(0.5)],
                }),
                OscPacket::Message(OscMessage {
                    addr: ADDR_BLEND_APPLY.into(),
                    args: vec![],
                }),
            ],
        });
        let bytes = rosc::encoder::encode(&bundle).unwrap();
        let msgs: Vec<_> = decode_packet(&bytes)
            .unwrap()
            .into_iter()
            .map(Result::unwrap)
            .collect();
        assert_eq!(
            msgs,
            vec![
                VmcMessage::RootPos {
                    name: "root".into(),
                    position: Vec3::new(0.0, 1.0, 2.0),
                    rotation: Quat::from_xyzw(3.0, 4.0, 5.0, 6.0),
                },
                VmcMessage::Ok { loaded: 1 },
                VmcMessage::BlendVal {
                    name: "A".into(),
                    value: 0.5
                },
                VmcMessage::BlendApply,
            ]
        );
    }

    #[test]
    fn decoder_reports_too_few_and_wrong_types() {
        let few = encode_msg(
            ADDR_BONE_POS,
            vec![OscType::String("Hips".into()), OscType::Float(1.0)],
        );
        assert_eq!(
            decode_packet(&few).unwrap(),
            vec![Err(VmcError::TooFewArgs {
                address: ADDR_BONE_POS.into(),
                expected: 8,
                got: 2
            })]
        );
        let mut args = vec![OscType::String("Hips".into())];
        args.extend((0..7).map(|_| OscType::Float(0.0)));
        args[3] = OscType::Int(3);
        let wrong = encode_msg(ADDR_BONE_POS, args);
        let r = decode_packet(&wrong).unwrap();
        assert!(
            matches!(
                &r[0],
                Err(VmcError::WrongType {
                    index: 3,
                    expected: "float",
                    ..
                })
            ),
            "{r:?}"
        );
        let name_not_string =
            encode_msg(ADDR_BLEND_VAL, vec![OscType::Int(1), OscType::Float(0.0)]);
        assert!(matches!(
            &decode_packet(&name_not_string).unwrap()[0],
            Err(VmcError::WrongType { index: 0, .. })
        ));
        let time = encode_msg(ADDR_TIME, vec![]);
        assert!(matches!(
            &decode_packet(&time).unwrap()[0],
            Err(VmcError::TooFewArgs { .. })
        ));
    }

    #[test]
    fn garbage_bytes_are_errors_not_panics() {
        let (names, t, r) = bones(10);
        let good = encode_all(&mut VmcEncoder::new(), &names, &t, &r).remove(0);
        let mut cases: Vec<Vec<u8>> = vec![
            vec![],
            vec![0],
            b"hello".to_vec(),
            b"#bundle\0".to_vec(),
            vec![0xff; 64],
            b"/VMC/Ext/T\0\0,f\0\0".to_vec(), // float argument missing
        ];
        for cut in [1, 7, 17, 20, 31, 100, good.len() - 1] {
            cases.push(good[..cut].to_vec());
        }
        // A bundle element size pointing past the end.
        let mut lying = good.clone();
        lying[16..20].copy_from_slice(&100_000i32.to_be_bytes());
        cases.push(lying);
        for (i, c) in cases.iter().enumerate() {
            match decode_packet(c) {
                Err(VmcError::Osc { .. }) => {}
                other => panic!("case {i}: expected an OSC error, got {other:?}"),
            }
        }
    }

    #[test]
    fn arrays_nested_deeper_than_the_limit_are_refused_before_decoding() {
        let message = |depth: usize| {
            let mut m = b"/VMC/Ext/T\0\0,".to_vec();
            m.extend(std::iter::repeat_n(b'[', depth));
            m.extend(std::iter::repeat_n(b']', depth));
            m.push(0);
            while !m.len().is_multiple_of(4) {
                m.push(0);
            }
            m
        };
        // 32,700 levels fit one datagram; decoded and dropped recursively they overflow.
        for depth in [MAX_ARRAY_DEPTH + 1, 32_700] {
            let plain = message(depth);
            assert!(matches!(decode_packet(&plain), Err(VmcError::Osc { .. })));
            let mut bundle = b"#bundle\0\0\0\0\0\0\0\0\x01".to_vec();
            bundle.extend_from_slice(&(plain.len() as i32).to_be_bytes());
            bundle.extend_from_slice(&plain);
            let err = check_osc_framing(&bundle).unwrap_err().to_string();
            assert!(err.contains("nests arrays"), "{err}");
        }
        // At the limit the framing passes (the decoder judges the rest).
        assert!(check_osc_framing(&message(MAX_ARRAY_DEPTH)).is_ok());
    }
}
