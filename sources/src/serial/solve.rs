//! Sensor orientations → local bone rotations, with pose calibration.
//!
//! A sensor is strapped to a bone at an unknown angle and reports its orientation `S` in its
//! own world frame (which differs from ours by the fixed change of basis `W`, e.g. Z-up → Y-up).
//! While the performer holds a known pose (T or N), [`ImuSolver::calibrate`] captures each
//! sensor's `S_c` and the bone's known world rotation `B_c`. Because the sensor is rigid on the
//! bone, the world rotation the bone made since calibration equals the sensor's:
//!
//! ```text
//!   B(t) = W · S(t) · S_c⁻¹ · W⁻¹ · B_c        (the mounting angle cancels out)
//! ```
//!
//! Local rotations then follow through the skeleton's parents: `local = parent_world⁻¹ · B`;
//! bones without a sensor keep their rest local rotation (so they follow their parent).

use std::sync::Arc;

use glam::Quat;
use rigcast_retarget::{world_transforms, BoneId, Pose, Skeleton};

use crate::error::SourceError;

/// Solves bone rotations from the latest sensor readings.
#[derive(Debug, Clone)]
pub struct ImuSolver {
    skeleton: Arc<Skeleton>,
    /// (sensor id, bone) per assignment.
    assignments: Vec<(u32, BoneId)>,
    /// Sensor assignment index per bone, if any.
    sensor_of_bone: Vec<Option<usize>>,
    latest: Vec<Option<Quat>>,
    /// `S_c⁻¹ · W⁻¹ · B_c` per assignment.
    right: Vec<Quat>,
    world_from_sensor_world: Quat,
    world: Vec<Quat>,
    calibrated: bool,
}

impl ImuSolver {
    /// A solver for `assignments` (sensor id → bone) on `skeleton`. Until calibrated, sensors
    /// are taken to read identity in the rest pose.
    pub fn new(
        skeleton: Arc<Skeleton>,
        assignments: Vec<(u32, BoneId)>,
        world_from_sensor_world: Quat,
    ) -> Result<ImuSolver, SourceError> {
        let n = skeleton.num_bones();
        let mut sensor_of_bone = vec![None; n];
        for (i, &(sensor, bone)) in assignments.iter().enumerate() {
            if bone.index() >= n {
                return Err(SourceError::InvalidOption {
                    reason: format!("sensor {sensor}: bone id {} out of range", bone.0),
                });
            }
            if sensor_of_bone[bone.index()].is_some() {
                return Err(SourceError::InvalidOption {
                    reason: format!("bone {:?} has more than one sensor", skeleton.name(bone)),
                });
            }
            if assignments[..i].iter().any(|(s, _)| *s == sensor) {
                return Err(SourceError::InvalidOption {
                    reason: format!("sensor {sensor} is assigned twice"),
                });
            }
            sensor_of_bone[bone.index()] = Some(i);
        }
        let w = world_from_sensor_world.normalize();
        let rest_world = world_transforms(&skeleton, &skeleton.rest_pose());
        let right = assignments
            .iter()
            .map(|(_, b)| w.inverse() * rest_world[b.index()].rotation)
            .collect();
        Ok(ImuSolver {
            latest: vec![None; assignments.len()],
            world: vec![Quat::IDENTITY; n],
            skeleton,
            assignments,
            sensor_of_bone,
            right,
            world_from_sensor_world: w,
            calibrated: false,
        })
    }

    /// The skeleton.
    pub fn skeleton(&self) -> &Arc<Skeleton> {
        &self.skeleton
    }

    /// True after a successful calibration.
    pub fn is_calibrated(&self) -> bool {
        self.calibrated
    }

    /// Records a reading; returns false for a sensor id that is not assigned.
    pub fn set_reading(&mut self, sensor: u32, rotation: Quat) -> bool {
        match self.assignments.iter().position(|(s, _)| *s == sensor) {
            Some(i) => {
                self.latest[i] = Some(rotation);
                true
            }
            None => false,
        }
    }

    /// Calibrates against `pose` (the pose the performer holds, e.g. the rest T-pose), using
    /// each sensor's latest reading. Fails, changing nothing, if a sensor has not reported yet.
    pub fn calibrate(&mut self, pose: &Pose) -> Result<(), SourceError> {
        pose.check(&self.skeleton)?;
        if let Some(i) = self.latest.iter().position(Option::is_none) {
            return Err(SourceError::InvalidOption {
                reason: format!(
                    "cannot calibrate: sensor {} has not sent a reading yet",
                    self.assignments[i].0
                ),
            });
        }
        let world = world_transforms(&self.skeleton, pose);
        let w_inv = self.world_from_sensor_world.inverse();
        for (i, (_, bone)) in self.assignments.iter().enumerate() {
            let s_c = self.latest[i].unwrap_or(Quat::IDENTITY);
            self.right[i] = (s_c.inverse() * w_inv * world[bone.index()].rotation).normalize();
        }
        self.calibrated = true;
        Ok(())
    }

    /// Writes local rotations (and rest translations) into `out`. Allocates nothing.
    pub fn solve(&mut self, out: &mut Pose) {
        let rest = self.skeleton.rest();
        let parents = self.skeleton.parents();
        for i in 0..self.skeleton.num_bones() {
            let parent_world = parents[i].map_or(Quat::IDENTITY, |p| self.world[p.index()]);
            let sensed = self.sensor_of_bone[i]
                .and_then(|a| self.latest[a].map(|s| (a, s)))
                .map(|(a, s)| (self.world_from_sensor_world * s * self.right[a]).normalize());
            let world = sensed.unwrap_or(parent_world * rest[i].rotation);
            self.world[i] = world;
            out.rotations[i] = (parent_world.inverse() * world).normalize();
            out.translations[i] = rest[i].translation;
        }
    }
}
