//! Stride warping and pelvis height: the root's move that carries the retargeted feet where the
//! source's stand, so the legs can stay exactly as retargeted.
//!
//! The retarget copies every limb's direction and scales the root's travel by the legs' ratio.
//! A rig whose legs are proportioned differently (thigh against shin, hip width, ankle height)
//! then slides a standing foot over the ground and holds it above or below the floor: bending
//! the leg to hold it bends it away from the performer's. Moving the whole body instead keeps
//! every leg the performer's:
//! - over the ground, the root takes up the standing feet's slide (each held foot's ankle
//!   moving since the frame before), so one standing foot holds still exactly; with two
//!   down, it takes up their mean and each leg keeps only half their disagreement (the IK's);
//!   with none down it holds where it is, brought back within a reach of where the animation
//!   puts it (a long walk would otherwise take the character ever farther from the performer's
//!   place; moving the body while no foot stands turns no leg), and while one is down it goes
//!   no farther than a second, wider reach (past it the legs take up the rest of the stride's
//!   difference);
//! - along up, the root stands the feet at their standing heights (when two are down, or one
//!   is landing, the height the caller finds for them together, `pelvis`; else their mean
//!   gap), held while none is (moved towards a landing foot's as it comes down); a change of
//!   which feet stand blends with a decaying offset, so the body never jumps. A caller that
//!   leaves heights to others passes a height limit of 0.

use glam::Vec3;

use super::spring::Decay;

/// One foot's part this frame.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct FootStand {
    /// The source's foot stands.
    pub stands: bool,
    /// It stood on the frame before as well, and its contact moved by this much since then
    /// (over the ground).
    pub slide: Option<Vec3>,
    /// How far its contact must move up to stand where it should.
    pub height_gap: f32,
    /// Live: how far over the ground the body must stand from where the animation puts it for
    /// this foot's leg to reach its pin as retargeted. Where every standing foot gives one, the
    /// body goes there (their mean), not by the slides since it stood (see `update`).
    pub pin_gap: Option<Vec3>,
}

/// The root's move onto the standing feet.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct RootShift {
    /// Over the ground: what the standing feet ask for (accumulated: the character's stride as
    /// its own legs make it); shown last frame, and its rate; shown minus wanted at the last
    /// change of the standing feet, decaying (the body's speed over the ground does not jump
    /// when a foot lands or lifts: the pinned feet's IK takes up the difference meanwhile).
    ground_wanted: Vec3,
    pub ground: Vec3,
    ground_rate: Vec3,
    ground_offset: Decay<Vec3>,
    /// Along up: what the standing feet ask for (held while none stands), and what they asked
    /// for last (what a landing foot moves it from as it comes down).
    wanted: f32,
    held: f32,
    /// Along up: shown last frame, and its rate; the wanted height's rate (it moves while a
    /// foot comes down to land).
    pub height: f32,
    rate: f32,
    wanted_rate: f32,
    /// Shown minus wanted at the last change of the standing feet, decaying.
    offset: Decay<f32>,
    /// Which feet stood last frame (a bit each).
    standing: u32,
    /// Since the last foot lifted, the body is being brought back within its reach.
    bringing_back: bool,
}

impl RootShift {
    /// Where the standing feet want the body over the ground this frame, `mean_slide` being
    /// their mean slide since the last. Live, where the standing legs reach their pins as
    /// retargeted (every standing foot's `pin_gap`, their mean): a foot is pinned where it is
    /// shown as it lands, a frame or two after the performer's (the causal detector), while the
    /// body may be moving (brought back within its reach); carried by the slides alone, that
    /// first gap stayed for the whole stance and the leg took it up (LaFAN1's walk onto
    /// Mousey: 2-3 cm, the thigh 7-13° off). Else moved on by the slides.
    fn ground_wanted_now(
        &self,
        feet: &[FootStand],
        up: Vec3,
        standing: u32,
        mean_slide: Vec3,
    ) -> Vec3 {
        let (mut pins, mut pinned) = (Vec3::ZERO, 0u32);
        for p in feet.iter().filter(|f| f.stands).filter_map(|f| f.pin_gap) {
            pins += p - up * p.dot(up);
            pinned += 1;
        }
        if pinned > 0 && pinned == standing {
            pins / pinned as f32
        } else {
            self.ground_wanted - mean_slide
        }
    }

    /// Takes this frame's feet (their gaps measured on the animation before any shift; `up` the
    /// floor's normal), `dt` after the last; `fresh`: nothing was shown before (the height is
    /// taken at once). `halflife`: the blends' half-lives over the ground and along up.
    /// `limits` bound the height's move either way and the move over the ground while no
    /// foot stands (blended in; what is left of it when a foot lands is dropped) and while
    /// one does. `height`:
    /// the height the caller found for the standing and landing feet together (see
    /// `pelvis`), with the share it takes (1 while a foot stands; a landing foot's weight while
    /// none does: the height moves that far from what the last standing feet asked for);
    /// without it, the standing feet's mean gap. Returns the standing feet's mean slide (what
    /// the root took up).
    pub fn update(
        &mut self,
        feet: &[FootStand],
        up: Vec3,
        fresh: bool,
        dt: f32,
        halflife: [f32; 2],
        limits: [f32; 3],
        height: Option<(f32, f32)>,
    ) -> Vec3 {
        let [halflife, height_halflife] = halflife;
        let [limit, reach, stance_reach] = limits;
        let (mut slide, mut sliding) = (Vec3::ZERO, 0u32);
        let (mut gap, mut standing_count) = (0.0f32, 0u32);
        let mut standing = 0u32;
        for (i, f) in feet.iter().enumerate().filter(|(_, f)| f.stands) {
            standing |= 1 << i;
            gap += f.height_gap;
            standing_count += 1;
            if let Some(s) = f.slide {
                slide += s - up * s.dot(up);
                sliding += 1;
            }
        }
        let mean_slide = if sliding > 0 {
            slide / sliding as f32
        } else {
            Vec3::ZERO
        };
        self.ground_wanted = self.ground_wanted_now(feet, up, standing_count, mean_slide);
        // Last frame's, moved on by this frame's slide: what a change of the standing feet
        // blends from (see below).
        let wanted_before = self.ground_wanted + mean_slide;
        // While a foot stands the root goes where its leg needs it (as far as `stance_reach`);
        // while none does, moving the body turns no leg, and it is brought back within
        // `reach`, blended in as a change of the standing feet is (below).
        let bound = if standing_count > 0 {
            stance_reach
        } else {
            reach
        };
        let unbounded = self.ground_wanted;
        let far = self.ground_wanted.length();
        if far > bound {
            self.ground_wanted *= bound / far;
        }
        let cut = unbounded - self.ground_wanted;
        let bound = |h: f32| crate::bounds::clamp_safe(h, -limit, limit);
        let height_before = self.wanted;
        match height {
            Some((h, _)) if standing_count > 0 => (self.wanted, self.held) = (bound(h), bound(h)),
            Some((h, share)) => {
                self.wanted = self.held + share.clamp(0.0, 1.0) * (bound(h) - self.held);
            }
            None if standing_count > 0 => {
                self.wanted = bound(gap / standing_count as f32);
                self.held = self.wanted;
            }
            None => self.wanted = self.held,
        }
        if fresh {
            self.offset = Decay::default();
            self.ground_offset = Decay::default();
            (self.rate, self.wanted_rate) = (0.0, 0.0);
        } else if standing != self.standing {
            // The body's speed kept, less what the wanted height's own speed goes on giving.
            self.offset = Decay {
                value: self.height - self.wanted,
                velocity: self.rate - self.wanted_rate,
            };
            let wanted_rate = if dt > 0.0 {
                -mean_slide / dt
            } else {
                Vec3::ZERO
            };
            // Against last frame's wanted, as the ground shown is last frame's: the offset
            // then steps over this frame with the wanted's move (against this frame's, the
            // body stood still for the frame of the change, a kick).
            self.ground_offset = Decay {
                value: self.ground - wanted_before,
                velocity: self.ground_rate - wanted_rate,
            };
            if self.standing == 0 && standing_count > 0 && self.bringing_back {
                // A foot lands: what is left of bringing the body back within `reach` is
                // dropped (its leg would have to take it up); the body goes on from where it
                // is shown.
                self.ground_wanted += self.ground_offset.value;
                self.ground_offset.value = Vec3::ZERO;
            }
        }
        if !fresh && standing == self.standing && dt > 0.0 {
            self.wanted_rate = (self.wanted - height_before) / dt;
        }
        self.standing = standing;
        if !fresh && standing_count == 0 {
            // Blended in: the body does not jump as its last foot lifts (a foot standing
            // takes its own cut a frame's slide at a time).
            self.ground_offset.value += cut;
            self.bringing_back |= cut != Vec3::ZERO;
        } else {
            self.bringing_back = false;
        }
        self.ground_offset.step(dt, halflife);
        let ground = self.ground_wanted + self.ground_offset.value;
        if dt > 0.0 {
            self.ground_rate = (ground - self.ground) / dt;
        }
        self.ground = ground;
        self.offset.step(dt, height_halflife);
        let height = self.wanted + self.offset.value;
        if dt > 0.0 && !fresh {
            self.rate = (height - self.height) / dt;
        }
        self.height = height;
        mean_slide
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One frame of 0.01 s of `s` (y up, half-lives 0.05 s, no fitted height), `limits` its
    /// height limit and reaches (no foot standing, one standing).
    fn frame(s: &mut RootShift, feet: &[FootStand], fresh: bool, limits: [f32; 3]) -> Vec3 {
        s.update(feet, Vec3::Y, fresh, 0.01, [0.05; 2], limits, None)
    }

    fn stand(slide: Option<Vec3>, gap: f32) -> FootStand {
        FootStand {
            stands: true,
            slide,
            height_gap: gap,
            pin_gap: None,
        }
    }

    #[test]
    fn one_standing_foot_is_held_exactly_two_share_their_disagreement() {
        let mut s = RootShift::default();
        let free = FootStand::default();
        frame(&mut s, &[stand(None, 0.0), free], true, [1.0; 3]);
        // One foot slides 1 cm forward (and 1 mm up, which is no slide over the ground).
        let m = frame(
            &mut s,
            &[stand(Some(Vec3::new(0.0, 0.001, 0.01)), 0.0), free],
            false,
            [1.0; 3],
        );
        assert!((s.ground - Vec3::new(0.0, 0.0, -0.01)).length() < 1e-6);
        assert!((m - Vec3::new(0.0, 0.0, 0.01)).length() < 1e-6);
        // Two feet sliding apart: the root takes up their mean.
        let m = frame(
            &mut s,
            &[
                stand(Some(Vec3::new(0.0, 0.0, 0.02)), 0.0),
                stand(Some(Vec3::ZERO), 0.0),
            ],
            false,
            [1.0; 3],
        );
        assert!((m - Vec3::new(0.0, 0.0, 0.01)).length() < 1e-6);
        assert!((s.ground_wanted - Vec3::new(0.0, 0.0, -0.02)).length() < 1e-6);
        // None standing: held.
        frame(&mut s, &[free, free], false, [1.0; 3]);
        assert!((s.ground_wanted - Vec3::new(0.0, 0.0, -0.02)).length() < 1e-6);
    }

    #[test]
    fn a_standing_foot_carries_the_body_where_its_leg_reaches_its_pin() {
        let limits = [1.0; 3];
        let free = FootStand::default();
        // A foot lands 2 cm ahead of where the animation's ankle is (it was pinned where it
        // was shown, the body moving meanwhile); the animation's foot does not slide.
        let gap = Vec3::new(0.0, 0.0, 0.02);
        let pinned = |gap: Vec3| FootStand {
            pin_gap: Some(gap + Vec3::Y * 0.01),
            ..stand(Some(Vec3::ZERO), 0.0)
        };
        let mut s = RootShift::default();
        frame(&mut s, &[free, free], true, limits);
        frame(&mut s, &[pinned(gap), free], false, limits);
        // Blended in, not a jump; then the body stands where the leg reaches the pin (the
        // gap's part along up is no move over the ground).
        assert!(s.ground.length() < 0.01, "{}", s.ground);
        for _ in 0..100 {
            frame(&mut s, &[pinned(gap), free], false, limits);
        }
        assert!((s.ground - gap).length() < 1e-4, "{}", s.ground);
        // Two standing: their mean.
        let other = Vec3::new(0.01, 0.0, 0.0);
        for _ in 0..100 {
            frame(&mut s, &[pinned(gap), pinned(other)], false, limits);
        }
        assert!(
            (s.ground - 0.5 * (gap + other)).length() < 1e-4,
            "{}",
            s.ground
        );
        // Without the pins' gaps (offline), the slides alone carry it: none, it stays.
        let mut s = RootShift::default();
        frame(&mut s, &[free, free], true, limits);
        for _ in 0..100 {
            frame(&mut s, &[stand(Some(Vec3::ZERO), 0.0), free], false, limits);
        }
        assert!(s.ground.length() < 1e-6, "{}", s.ground);
    }

    #[test]
    fn the_height_is_taken_at_once_first_then_blended_and_held() {
        let mut s = RootShift::default();
        frame(&mut s, &[stand(None, 0.03)], true, [0.2, 1.0, 1.0]);
        assert!((s.height - 0.03).abs() < 1e-6, "{}", s.height);
        frame(&mut s, &[stand(None, 0.03)], false, [0.2, 1.0, 1.0]);
        assert!((s.height - 0.03).abs() < 1e-6);
        // It lifts: held.
        frame(&mut s, &[FootStand::default()], false, [0.2, 1.0, 1.0]);
        assert!((s.height - 0.03).abs() < 1e-6, "{}", s.height);
        // Another lands wanting 5 cm: blended towards it, no jump.
        let mut last = s.height;
        for _ in 0..60 {
            frame(&mut s, &[stand(None, 0.05)], false, [0.2, 1.0, 1.0]);
            assert!(
                s.height >= last - 1e-6 && s.height - last < 0.006,
                "{}",
                s.height
            );
            last = s.height;
        }
        assert!((s.height - 0.05).abs() < 1e-3, "{}", s.height);
        // Bounded.
        frame(&mut s, &[stand(None, 5.0)], true, [0.2, 1.0, 1.0]);
        assert!((s.height - 0.2).abs() < 1e-6);
    }

    #[test]
    fn the_root_is_carried_past_its_reach_only_while_a_foot_stands() {
        let limits = [1.0, 0.3, 0.5];
        let slide = stand(Some(Vec3::new(0.0, 0.0, 0.01)), 0.0);
        let free = FootStand::default();
        let mut s = RootShift::default();
        frame(&mut s, &[stand(None, 0.0)], true, limits);
        // The standing foot slides 1 cm a frame forward, 100 frames (a metre): the root is
        // carried back 50 cm at most while it stands, however long it slides.
        for _ in 0..100 {
            frame(&mut s, &[slide], false, limits);
            assert!(s.ground.length() <= 0.5 + 1e-5, "{}", s.ground);
        }
        assert!((s.ground - Vec3::new(0.0, 0.0, -0.5)).length() < 1e-5);
        // It lifts: the body comes back within 30 cm, without a jump.
        let mut last = s.ground;
        for _ in 0..100 {
            frame(&mut s, &[free], false, limits);
            assert!((s.ground - last).length() < 0.03, "{} {}", s.ground, last);
            last = s.ground;
        }
        assert!(
            (s.ground - Vec3::new(0.0, 0.0, -0.3)).length() < 1e-3,
            "{}",
            s.ground
        );
        // Carried out again, one frame free, then a foot lands: the body stays where it was
        // shown as it landed (its leg would take up the rest), its speed blending out.
        for _ in 0..100 {
            frame(&mut s, &[slide], false, limits);
        }
        frame(&mut s, &[free], false, limits);
        let landed = s.ground;
        assert!(landed.length() > 0.4, "{landed}");
        frame(&mut s, &[stand(None, 0.0)], false, limits);
        for _ in 0..100 {
            frame(&mut s, &[stand(Some(Vec3::ZERO), 0.0)], false, limits);
        }
        assert!((s.ground - landed).length() < 0.02, "{} {landed}", s.ground);
    }
}
