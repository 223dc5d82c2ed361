//! Which target bones keep their own posture: where a source's reference posture means
//! something else on the target, copying the source's directions would make the target take
//! the source's posture (a horse reared up like the walker driving it, its front legs held out
//! like the walker's arms in its T-pose, its zig-zag legs straightened like the walker's).
//! Such bones instead keep the target's standing posture and follow the source bone's motion
//! from the source's own standing posture ([`crate::RetargetOptions::posture_relative`]).

use super::MappingTable;
use crate::analysis::{Analysis, Role, SectionKind};
use crate::skeleton::BoneId;

/// What a posture-relative bone ([`crate::RetargetOptions::posture_relative`]) takes of its source
/// bone's world rotation relative to the source's standing posture.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Follow {
    /// All of it.
    Rotation,
    /// Only its turn about the source's up: a quadruped's trunk stays level while the walker
    /// driving it leans, and still turns with it.
    Heading,
}

/// Number of limbs (arms and legs) reaching the ground.
fn ground_limbs(a: &Analysis) -> usize {
    a.sections
        .iter()
        .filter(|s| s.ground && matches!(s.kind, SectionKind::Arm | SectionKind::Leg))
        .count()
}

/// Whether `bone` is the trunk proper: hips to chest (not the neck and head).
fn trunk(a: &Analysis, bone: BoneId) -> bool {
    let r = a.roles[bone.index()];
    matches!(
        r.role,
        Role::Hips | Role::Spine | Role::SpineMid | Role::Chest
    ) || r
        .section
        .and_then(|s| a.sections.get(s as usize))
        .is_some_and(|s| s.kind == SectionKind::Spine)
}

/// The mapped target bones of `table` whose primary source bone's posture means something else
/// on the target: when the target stands on more limbs than that source (a quadruped driven by
/// a walker), every one of them, since neither its trunk (level, not upright), nor its front
/// legs (down, not the arms of a T-pose), nor its legs' zig-zag are the source's. The trunk
/// proper (hips to chest) follows only the source's heading ([`Follow::Heading`]): it stays
/// level while the walker leans; everything else follows the whole rotation. `sources[i]` is
/// input `i`'s analysis. Empty for two characters built alike (a human driving a human).
pub fn posture_relative(
    table: &MappingTable,
    sources: &[&Analysis],
    target: &Analysis,
) -> Vec<(BoneId, Follow)> {
    let stands_on = ground_limbs(target);
    let mut out = Vec::new();
    for (i, e) in table.entries.iter().enumerate() {
        let Some(s) = e
            .as_ref()
            .and_then(|e| e.sources.iter().find(|s| s.weight > 0.0))
        else {
            continue;
        };
        let (t, Some(sa)) = (BoneId(i as u16), sources.get(s.input as usize)) else {
            continue;
        };
        if t.index() >= target.roles.len() || stands_on <= ground_limbs(sa).max(2) {
            continue;
        }
        let follow = if trunk(target, t) {
            Follow::Heading
        } else {
            Follow::Rotation
        };
        out.push((t, follow));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::{analyze, SkeletonView};
    use crate::mapping::{auto_map, MapOptions};

    #[test]
    fn only_a_target_on_more_legs_keeps_its_posture() {
        let human = crate::corpus::get("cmu_max").expect("corpus");
        let view = SkeletonView::rest(&human.skeleton);
        let a = analyze(&view);
        let table = auto_map(&view, &view, &MapOptions::default());
        assert!(posture_relative(&table, &[&a], &a).is_empty());
        // A walker driving a horse: every mapped bone, the trunk by its heading alone.
        let horse = crate::corpus::get("horse").expect("corpus");
        let hview = SkeletonView::rest(&horse.skeleton);
        let h = analyze(&hview);
        let table = auto_map(&view, &hview, &MapOptions::default());
        let relative = posture_relative(&table, &[&a], &h);
        assert_eq!(relative.len(), table.num_mapped());
        let hips = h
            .find(Role::Hips, crate::analysis::Side::Center)
            .expect("hips");
        assert!(relative.contains(&(hips, Follow::Heading)));
        assert!(relative.iter().any(|&(_, f)| f == Follow::Rotation));
    }
}
