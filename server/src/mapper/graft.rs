//! A grafted performer's mapping: the upper source mapped onto the character, the lower body
//! (a second source, or a clip) mapped separately, spliced at the waist (`graft_live`).

use std::sync::Arc;

use anyhow::Context;
use rigcast_engine::graft_live::{LiveGraft, LowerInput};
use rigcast_engine::performer::BuiltMapping;
use rigcast_retarget::analysis::{analyze_with_truth, Analysis, SkeletonView};
use rigcast_retarget::mapping::{apply_overrides, map_analyzed, MappingTable};
use rigcast_retarget::{Clip, Mapping, Pose, RetargetOptions, RootMotion, Skeleton};

use super::{apply_session, build_foot_lock, mapping_report, target_view, Mapper, PerformerPlan};

/// One half's source as the graft maps it.
struct Side {
    skeleton: Arc<Skeleton>,
    analysis: Analysis,
    /// A representative pose (for alignment when the rest pose has no posture).
    reference: Option<Pose>,
    /// The source's poses (for its floor height); empty for a live source.
    poses: Arc<Vec<Pose>>,
}

impl Mapper {
    /// Builds a grafted performer's mapping. Overrides (file and session) apply to the upper
    /// body's table.
    pub(super) fn build_graft(&mut self, i: usize) -> anyhow::Result<()> {
        let p = &self.performers[i];
        let target = p.target.skeleton();
        let ta = analyze_with_truth(&target_view(&target, p), p.target.truth());
        let (upper, lower, clip) = self.graft_sides(p)?;
        let upper_table = self.upper_table(p, &upper, (&target, &ta))?;
        let lower_table = self.table_for(&lower, &target, &ta);
        let upper_mapping = Mapping::build(
            &[&upper.skeleton],
            &target,
            &upper_table,
            &self.side_options(p, &ta, &upper, RootMotion::InPlace),
        )
        .context("cannot build the upper body's mapping")?;
        let mut lower_mapping = Mapping::build(
            &[&lower.skeleton],
            &target,
            &lower_table,
            &self.side_options(p, &ta, &lower, p.root_motion),
        )
        .context("cannot build the lower body's mapping")?;
        if let Some(floor) = lower_mapping.measure_source_floor(&lower.poses) {
            lower_mapping.set_source_floor_y(floor);
        }
        let foot_lock = build_foot_lock(
            &lower_mapping,
            std::slice::from_ref(&lower.analysis),
            &ta,
            p.foot_lock,
        );
        let graft = LiveGraft::new(
            &upper_mapping,
            lower_mapping,
            &lower.analysis,
            &ta,
            clip.as_deref(),
        )?;
        // The `mapping` message: each target bone's source from the table of its half.
        let merged =
            rigcast_engine::graft_live::merged_table(&upper_table, &lower_table, graft.split());
        let report = mapping_report(
            &p.target,
            &[upper.skeleton.clone(), lower.skeleton.clone()],
            &target,
            &ta,
            &merged,
            &self.options,
            warnings(&upper, &lower, &ta),
        );
        self.hand_over(
            i,
            BuiltMapping {
                mapping: upper_mapping,
                foot_lock,
                graft: Some(graft),
            },
            report,
        );
        Ok(())
    }

    /// The graft's halves: the upper body's source, the lower body's (a second source or the
    /// clip), and the clip if it is one.
    fn graft_sides(&self, p: &PerformerPlan) -> anyhow::Result<(Side, Side, Option<Arc<Clip>>)> {
        let upper_id = *p
            .target
            .inputs
            .first()
            .context("a graft without an upper source")?;
        let upper = self.source_side(upper_id);
        let clip = match &p.graft {
            Some(LowerInput::Clip(c)) => Some(c.clone()),
            _ => None,
        };
        let lower = match &clip {
            Some(c) => clip_side(c),
            None => {
                let lower_id = *p
                    .target
                    .inputs
                    .get(1)
                    .context("a graft without a lower source")?;
                self.source_side(lower_id)
            }
        };
        Ok((upper, lower, clip))
    }

    /// The upper body's table, with the performer's mapping file and session overrides.
    fn upper_table(
        &self,
        p: &PerformerPlan,
        upper: &Side,
        (target, ta): (&Skeleton, &Analysis),
    ) -> anyhow::Result<MappingTable> {
        let mut table = self.table_for(upper, target, ta);
        if let Some(file) = &p.overrides_file {
            apply_overrides(&mut table, file, &[&upper.skeleton], target)
                .context("mapping file")?;
        }
        apply_session(&mut table, &p.session, &[&upper.skeleton], target)?;
        Ok(table)
    }

    /// A live or replayed source subject as one half of a graft.
    fn source_side(&self, id: u32) -> Side {
        let subject = &self.subjects[id as usize];
        let extra = self.extras.get(&id);
        let skeleton = subject.skeleton();
        let reference = extra.and_then(|e| e.reference.clone());
        let analysis = analyze_with_truth(
            &SkeletonView::with_pose(&skeleton, reference.as_ref()),
            subject.truth(),
        );
        let poses = extra.map(|e| e.poses.clone()).unwrap_or_default();
        Side {
            skeleton,
            analysis,
            reference,
            poses,
        }
    }

    /// One half's automatic table onto the character.
    fn table_for(&self, side: &Side, target: &Skeleton, ta: &Analysis) -> MappingTable {
        map_analyzed(
            &[(&side.skeleton, &side.analysis)],
            (target, ta),
            &self.options,
        )
    }

    /// The retarget options of one half (its references count only where its analysis used
    /// them).
    fn side_options(
        &self,
        p: &PerformerPlan,
        ta: &Analysis,
        side: &Side,
        root_motion: RootMotion,
    ) -> RetargetOptions {
        RetargetOptions {
            frame_time_secs: self.frame_time_secs,
            root_motion,
            source_reference: vec![side.reference.clone().filter(|_| side.analysis.used_pose)],
            target_reference: p.target_reference.clone().filter(|_| ta.used_pose),
            source_up: Some(side.analysis.up),
            ..RetargetOptions::default()
        }
    }
}

/// A clip as the graft's lower half: analysed from its own motion.
fn clip_side(clip: &Clip) -> Side {
    let analysis = analyze_with_truth(&SkeletonView::from_clip(&clip.skeleton, &clip.poses), None);
    let reference = analysis.posture_pose(&clip.poses);
    Side {
        skeleton: clip.skeleton.clone(),
        analysis,
        reference,
        poses: Arc::new(clip.poses.clone()),
    }
}

/// The analyses' warnings, each said of its part.
fn warnings(upper: &Side, lower: &Side, target: &Analysis) -> Vec<String> {
    [
        ("upper source", &upper.analysis),
        ("lower body", &lower.analysis),
        ("target", target),
    ]
    .iter()
    .flat_map(|(who, a)| a.warnings.iter().map(move |w| format!("{who}: {w}")))
    .collect()
}
