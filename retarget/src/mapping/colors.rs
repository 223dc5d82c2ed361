//! Mapping colours (seed 000 §3.3): a gradient along each chain and a random-but-stable colour
//! per mapped pair, so clients can colour both skeletons and spot a wrong match at a glance.

use serde::{Deserialize, Serialize};

use super::table::MappingTable;
use crate::analysis::Analysis;
use crate::skeleton::Skeleton;

/// Display colours of one mapped target bone (RGB, 0..1). The source bone(s) driving it use
/// the same colours.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BoneColors {
    /// Hue per section, brightening along the chain from the body outwards.
    pub gradient: [f32; 3],
    /// Random but stable for the (target, source) pair: easier to tell neighbours apart.
    pub random: [f32; 3],
}

/// Grey used for unmapped bones by clients.
pub const UNMAPPED: [f32; 3] = [0.5, 0.5, 0.5];

fn hsv(h: f32, s: f32, v: f32) -> [f32; 3] {
    let h = h.rem_euclid(1.0) * 6.0;
    let i = h.floor();
    let f = h - i;
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    match i as u32 {
        0 => [v, t, p],
        1 => [q, v, p],
        2 => [p, v, t],
        3 => [p, q, v],
        4 => [t, p, v],
        _ => [v, p, q],
    }
}

fn fnv(bytes: &[u8], mut h: u64) -> u64 {
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// Colours for every target bone (`None` = unmapped), from the target's analysis (sections
/// give the chains) and the table.
pub fn mapping_colors(
    target: &Skeleton,
    analysis: &Analysis,
    table: &MappingTable,
) -> Vec<Option<BoneColors>> {
    target
        .bone_ids()
        .map(|t| {
            let entry = table.get(t)?;
            let src = entry.primary()?;
            let role = analysis.roles.get(t.index())?;
            // Golden-ratio hue steps keep neighbouring sections apart.
            let section = role.section.map(|s| s as f32).unwrap_or(0.0);
            let hue = (section * 0.618_034).fract();
            let gradient = hsv(hue, 0.75, 0.45 + 0.5 * role.position.clamp(0.0, 1.0));
            let mut h = fnv(target.name(t).as_bytes(), 0xcbf2_9ce4_8422_2325);
            h = fnv(&src.input.to_le_bytes(), h);
            h = fnv(&src.bone.0.to_le_bytes(), h);
            let random = hsv(
                (h & 0xffff) as f32 / 65536.0,
                0.55 + 0.4 * ((h >> 16) & 0xff) as f32 / 255.0,
                0.7 + 0.3 * ((h >> 24) & 0xff) as f32 / 255.0,
            );
            Some(BoneColors { gradient, random })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hsv_primaries() {
        assert_eq!(hsv(0.0, 1.0, 1.0), [1.0, 0.0, 0.0]);
        let g = hsv(1.0 / 3.0, 1.0, 1.0);
        assert!(g[1] > 0.99 && g[0] < 0.01 && g[2] < 0.01);
        assert_eq!(hsv(0.5, 0.0, 0.5), [0.5, 0.5, 0.5]);
    }
}
