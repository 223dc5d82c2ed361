//! Acceptance (issue 4): steady-state `Mapping::apply` allocates nothing — checked with a
//! counting global allocator, on a mapping that uses every per-frame feature (direction fixes,
//! many-to-one blending, delays with a history ring, reverse, weights, root motion with foot
//! contact, chain distribution, two inputs).

mod alloc_count;
mod retarget_fixtures;

use retarget_fixtures::{motion, table_by_canonical, Axes, Humanoid};
use rigcast_retarget::mapping::SourceRef;
use rigcast_retarget::{FootContact, Mapping, RetargetOptions};

use alloc_count::allocations;

#[test]
fn steady_state_apply_allocates_nothing() {
    let source_spec = Humanoid::default();
    let other_spec = Humanoid {
        prefix: "b:",
        ..Humanoid::default()
    };
    let target_spec = Humanoid {
        arm_down_deg: 45.0,
        axes: Axes::AlongBone { roll_rad: 0.3 },
        leg: 1.2,
        // One more spine bone than the source: an unmapped interior bone for distribution.
        spine_bones: 3,
        ..Humanoid::default()
    };
    let source = source_spec.build();
    let second = other_spec.build();
    let target = target_spec.build();
    let mut table = table_by_canonical(&source, "", &target, "");
    // Blend the head from both inputs, delay the hands, reverse and half-weight the forearms.
    for t in target.bone_ids() {
        let name = target.name(t).to_string();
        let Some(e) = table.entries[t.index()].as_mut() else {
            continue;
        };
        match name.as_str() {
            "head" => e.sources.push(SourceRef {
                input: 1,
                bone: second.bone("b:head").expect("head"),
                weight: 0.5,
            }),
            "l_hand" | "r_hand" => e.options.delay_secs = 0.1,
            "l_forearm" => e.options.reverse = true,
            "r_forearm" => e.options.weight = 0.5,
            _ => {}
        }
    }
    let opts = RetargetOptions {
        distribute_chains: true,
        foot_contact: FootContact::EveryFrame,
        ..RetargetOptions::default()
    };
    let mut mapping = Mapping::build(&[&source, &second], &target, &table, &opts).expect("build");
    let a = motion(&source, 50, 0.0, 1.0);
    let b = motion(&second, 50, 0.0, 1.0);
    let mut out = mapping.new_target_pose();
    // Warm-up frame (fills the history ring).
    mapping.apply(&[&a[0], &b[0]], &mut out).expect("apply");
    let before = allocations();
    for f in 1..50 {
        mapping.apply(&[&a[f], &b[f]], &mut out).expect("apply");
    }
    let during = allocations() - before;
    assert_eq!(during, 0, "apply allocated {during} times in 49 frames");
    // The counter works: building allocates.
    let before = allocations();
    let _again = Mapping::build(&[&source, &second], &target, &table, &opts);
    assert!(allocations() > before);
}
