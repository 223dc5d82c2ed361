//! The search features of real clips, as the motion graph computes them (each clip's body
//! points, measured and windowed with the graph's settings): shared by the real-clip graph
//! tests and benches, which run the transition search on its own.

use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::graph::body::BodyPoints;
use rigcast_retarget::graph::features::{ClipFeatures, ClipTrack};
use rigcast_retarget::graph::GraphSettings;
use rigcast_retarget::Clip;

/// One [`ClipFeatures`] per clip, all at the first clip's frame time.
pub fn clip_features(clips: &[Clip], s: &GraphSettings) -> Vec<ClipFeatures> {
    let ft = clips[0].frame_time_secs;
    clips
        .iter()
        .map(|c| {
            let a = analyze(&SkeletonView::from_clip(&c.skeleton, &c.poses));
            let body = BodyPoints::find(&a).expect("humanoid");
            let track = ClipTrack::measure(&c.skeleton, &body, &c.poses);
            let half = GraphSettings::frames(s.window_secs / 2.0, ft, 1);
            ClipFeatures::compute(&track, half, ft as f32, s.velocity_weight_secs)
        })
        .collect()
}
