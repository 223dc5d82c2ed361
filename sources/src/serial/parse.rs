//! Byte-stream parsers for serial IMU formats. Each keeps a small fixed buffer, resynchronises
//! after garbage, counts what it drops and allocates nothing.
//!
//! * CSV lines `id,w,x,y,z` (`\n` or `\r\n`; blank lines and `#` comments skipped).
//! * WitMotion 11-byte frames: `0x55`, type, 8 data bytes, checksum = low byte of the sum of
//!   the first 10. Type `0x59` is a quaternion: four little-endian `i16` (w, x, y, z) / 32768.
//!   Other types (acceleration, gyro, angles) are valid but carry no orientation: skipped.
//! * InvenSense "teapot" packets (14 bytes): `$`, `0x02`, four big-endian Q14 `i16`
//!   (w, x, y, z), `0x00`, a counter, `\r`, `\n`.
//!
//! WitMotion and teapot carry one sensor per port: their samples are sensor 0.

use glam::Quat;
use serde::{Deserialize, Serialize};

/// Serial IMU wire format.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ImuFormat {
    /// Text lines `id,w,x,y,z`.
    #[default]
    Csv,
    /// WitMotion binary frames (quaternion type 0x59).
    #[serde(rename = "witmotion")]
    WitMotion,
    /// InvenSense teapot packets.
    Teapot,
}

/// One orientation reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuSample {
    /// Sensor id (CSV `id`; 0 for single-sensor binary formats).
    pub sensor: u32,
    /// Sensor orientation in the sensor's world frame, normalised.
    pub rotation: Quat,
}

const LINE_MAX: usize = 128;
const WIT_LEN: usize = 11;
const TEAPOT_LEN: usize = 14;

/// Incremental parser for one [`ImuFormat`].
#[derive(Debug, Clone)]
pub struct ImuParser {
    format: ImuFormat,
    buf: [u8; LINE_MAX],
    len: usize,
    overflow: bool,
}

impl ImuParser {
    /// A parser for `format`.
    pub fn new(format: ImuFormat) -> Self {
        ImuParser {
            format,
            buf: [0; LINE_MAX],
            len: 0,
            overflow: false,
        }
    }

    /// Forgets any partial line/frame (after a reconnect).
    pub fn reset(&mut self) {
        self.len = 0;
        self.overflow = false;
    }

    /// Feeds bytes; calls `on_sample` per complete reading. Returns how many lines/frames were
    /// dropped as malformed.
    pub fn feed(&mut self, bytes: &[u8], mut on_sample: impl FnMut(ImuSample)) -> u64 {
        let mut dropped = 0;
        for &b in bytes {
            dropped += match self.format {
                ImuFormat::Csv => self.csv_byte(b, &mut on_sample),
                ImuFormat::WitMotion => self.frame_byte(b, 0x55, WIT_LEN, &mut on_sample),
                ImuFormat::Teapot => self.frame_byte(b, b'$', TEAPOT_LEN, &mut on_sample),
            };
        }
        dropped
    }

    fn csv_byte(&mut self, b: u8, on_sample: &mut impl FnMut(ImuSample)) -> u64 {
        if b != b'\n' {
            if self.len < LINE_MAX {
                self.buf[self.len] = b;
                self.len += 1;
            } else {
                self.overflow = true;
            }
            return 0;
        }
        let line_len = self.len;
        let overflow = self.overflow;
        self.len = 0;
        self.overflow = false;
        if overflow {
            return 1;
        }
        let line = trim(&self.buf[..line_len]);
        if line.is_empty() || line[0] == b'#' {
            return 0;
        }
        match parse_csv(line) {
            Some(s) => {
                on_sample(s);
                0
            }
            None => 1,
        }
    }

    fn frame_byte(
        &mut self,
        b: u8,
        start: u8,
        frame_len: usize,
        on_sample: &mut impl FnMut(ImuSample),
    ) -> u64 {
        if self.len == 0 && b != start {
            return 0; // between frames: noise, skipped until a start byte
        }
        self.buf[self.len] = b;
        self.len += 1;
        if self.len < frame_len {
            return 0;
        }
        let decoded = match self.format {
            ImuFormat::WitMotion => decode_witmotion(&self.buf[..WIT_LEN]),
            _ => decode_teapot(&self.buf[..TEAPOT_LEN]),
        };
        match decoded {
            Some(sample) => {
                self.len = 0;
                if let Some(s) = sample {
                    on_sample(s);
                }
                0
            }
            None => {
                // Resynchronise at the next start byte inside the rejected frame.
                let next = self.buf[1..frame_len].iter().position(|&c| c == start);
                match next {
                    Some(i) => {
                        self.buf.copy_within(i + 1..frame_len, 0);
                        self.len = frame_len - i - 1;
                    }
                    None => self.len = 0,
                }
                1
            }
        }
    }
}

fn trim(mut s: &[u8]) -> &[u8] {
    while let [first, rest @ ..] = s {
        if first.is_ascii_whitespace() {
            s = rest;
        } else {
            break;
        }
    }
    while let [rest @ .., last] = s {
        if last.is_ascii_whitespace() {
            s = rest;
        } else {
            break;
        }
    }
    s
}

fn parse_csv(line: &[u8]) -> Option<ImuSample> {
    let text = std::str::from_utf8(line).ok()?;
    let mut fields = text.split(',').map(str::trim);
    let sensor: u32 = fields.next()?.parse().ok()?;
    let mut v = [0f32; 4];
    for slot in &mut v {
        *slot = fields.next()?.parse().ok()?;
    }
    if fields.next().is_some() {
        return None;
    }
    let [w, x, y, z] = v;
    quat_from_wxyz(w, x, y, z).map(|rotation| ImuSample { sensor, rotation })
}

/// A normalised quaternion, or None when not finite or far from unit length.
fn quat_from_wxyz(w: f32, x: f32, y: f32, z: f32) -> Option<Quat> {
    let q = Quat::from_xyzw(x, y, z, w);
    let len = q.length();
    if !len.is_finite() || !(0.5..=2.0).contains(&len) {
        return None;
    }
    Some(q / len)
}

/// Some(None) for a valid frame without orientation; None for a corrupt frame.
fn decode_witmotion(f: &[u8]) -> Option<Option<ImuSample>> {
    let sum = f[..10].iter().fold(0u8, |a, b| a.wrapping_add(*b));
    if sum != f[10] {
        return None;
    }
    if f[1] != 0x59 {
        return Some(None);
    }
    let c = |i: usize| i16::from_le_bytes([f[2 + 2 * i], f[3 + 2 * i]]) as f32 / 32768.0;
    Some(
        quat_from_wxyz(c(0), c(1), c(2), c(3)).map(|rotation| ImuSample {
            sensor: 0,
            rotation,
        }),
    )
}

fn decode_teapot(f: &[u8]) -> Option<Option<ImuSample>> {
    if f[1] != 0x02 || f[10] != 0 || f[12] != b'\r' || f[13] != b'\n' {
        return None;
    }
    let c = |i: usize| i16::from_be_bytes([f[2 + 2 * i], f[3 + 2 * i]]) as f32 / 16384.0;
    let q = quat_from_wxyz(c(0), c(1), c(2), c(3))?;
    Some(Some(ImuSample {
        sensor: 0,
        rotation: q,
    }))
}

/// Encodes a WitMotion quaternion frame (for tests, simulators and recordings).
pub fn witmotion_frame(q: Quat) -> [u8; WIT_LEN] {
    let mut f = [0u8; WIT_LEN];
    f[0] = 0x55;
    f[1] = 0x59;
    for (i, v) in [q.w, q.x, q.y, q.z].into_iter().enumerate() {
        let n = (v * 32768.0).round().clamp(-32768.0, 32767.0) as i16;
        f[2 + 2 * i..4 + 2 * i].copy_from_slice(&n.to_le_bytes());
    }
    f[10] = f[..10].iter().fold(0u8, |a, b| a.wrapping_add(*b));
    f
}

/// Encodes a teapot packet (for tests, simulators and recordings).
pub fn teapot_packet(q: Quat, counter: u8) -> [u8; TEAPOT_LEN] {
    let mut f = [0u8; TEAPOT_LEN];
    f[0] = b'$';
    f[1] = 0x02;
    for (i, v) in [q.w, q.x, q.y, q.z].into_iter().enumerate() {
        let n = (v * 16384.0).round().clamp(-32768.0, 32767.0) as i16;
        f[2 + 2 * i..4 + 2 * i].copy_from_slice(&n.to_be_bytes());
    }
    f[11] = counter;
    f[12] = b'\r';
    f[13] = b'\n';
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    fn collect(p: &mut ImuParser, bytes: &[u8]) -> (Vec<ImuSample>, u64) {
        let mut out = Vec::new();
        let d = p.feed(bytes, |s| out.push(s));
        (out, d)
    }

    #[test]
    fn csv_lines_split_anywhere() {
        let mut p = ImuParser::new(ImuFormat::Csv);
        let text = b"1,1,0,0,0\r\n# comment\n\n2, 0.7071, 0.7071, 0, 0\nbad\n3,1,2\n4,nan,0,0,1\n5,0,0,0,0\n";
        let mut all = Vec::new();
        let mut dropped = 0;
        for chunk in text.chunks(3) {
            let (s, d) = collect(&mut p, chunk);
            all.extend(s);
            dropped += d;
        }
        assert_eq!(all.len(), 2);
        assert_eq!(all[0].sensor, 1);
        assert!((all[1].rotation.x - std::f32::consts::FRAC_1_SQRT_2).abs() < 1e-4);
        assert_eq!(dropped, 4);
        let (s, d) = collect(&mut p, &[b'9'; 300]);
        assert!(s.is_empty() && d == 0);
        assert_eq!(collect(&mut p, b"\n").1, 1, "overlong line dropped");
    }

    #[test]
    fn witmotion_resyncs_after_bad_checksum_and_noise() {
        let q = Quat::from_rotation_z(0.5);
        let good = witmotion_frame(q);
        let mut bad = good;
        bad[10] ^= 1;
        let mut accel = [0x55, 0x51, 1, 2, 3, 4, 5, 6, 7, 8, 0];
        accel[10] = accel[..10].iter().fold(0u8, |a, b| a.wrapping_add(*b));
        let mut stream = vec![0x00, 0x13, 0x55];
        stream.extend_from_slice(&bad);
        stream.extend_from_slice(&accel);
        stream.extend_from_slice(&good);
        let mut p = ImuParser::new(ImuFormat::WitMotion);
        let (s, d) = collect(&mut p, &stream);
        assert_eq!(s.len(), 1);
        assert!(s[0].rotation.angle_between(q) < 1e-3);
        assert!(d >= 1);
    }

    #[test]
    fn teapot_round_trip() {
        let q = Quat::from_rotation_x(-1.0);
        let mut p = ImuParser::new(ImuFormat::Teapot);
        let mut stream = b"junk$".to_vec();
        stream.extend_from_slice(&teapot_packet(q, 7));
        let (s, _) = collect(&mut p, &stream);
        assert_eq!(s.len(), 1);
        assert!(s[0].rotation.angle_between(q) < 1e-3);
    }
}
