//! Issue 35's split of a pair's thigh and shin errors by the leg's phase, shared by the offline
//! judge (`retarget_quality`'s `locked_legs`) and the live one (`footlock_live_legs`) so both
//! read and print the phases alike.

/// A leg's phases: its source foot standing alone (0) or with the other (1), the
/// [`PHASE_NEAR_SECS`] before a stance (2, approach) and after one (3, release), swinging (4).
pub const PHASES: usize = 5;
pub const PHASE_NAMES: [&str; PHASES] = ["single", "double", "approach", "release", "swing"];

/// How long (seconds) before a plant a free foot is approaching it, and after a release
/// leaving it.
pub const PHASE_NEAR_SECS: f64 = 0.15;

/// Per segment (thigh, shin) and phase: frames measured, frames over 8° (the p95 bound), the
/// summed error.
pub type PhaseSums = [[(usize, usize, f32); PHASES]; 2];

/// The phase of side `si` on `frame`, from each side's stances (`stands[side][frame]`) and
/// `near`, [`PHASE_NEAR_SECS`] in frames.
pub fn phase(stands: &[Vec<bool>], si: usize, frame: usize, near: usize) -> usize {
    let at = |s: usize, f: usize| stands.get(s).and_then(|v| v.get(f)) == Some(&true);
    if at(si, frame) {
        return if at(1 - si, frame) { 1 } else { 0 };
    }
    if (1..=near).any(|k| at(si, frame + k)) {
        2
    } else if (1..=near.min(frame)).any(|k| at(si, frame - k)) {
        3
    } else {
        4
    }
}

/// Adds a pair's thigh and shin errors per phase to `sums`.
pub fn tally_phases(sums: &mut PhaseSums, phases: &[[Vec<f32>; PHASES]; 2]) {
    for (sum, errors) in sums.iter_mut().zip(phases) {
        for ((n, over, total), e) in sum.iter_mut().zip(errors) {
            *n += e.len();
            *over += e.iter().filter(|e| **e > 8.0).count();
            *total += e.iter().sum::<f32>();
        }
    }
}

/// Prints a pair's thigh and shin errors per phase: frames, mean/p95, and how many of those
/// frames are over 8° (what puts a pair's p95 over its bound).
pub fn print_phases(phases: &[[Vec<f32>; PHASES]; 2]) {
    for (segment, errors) in ["thigh", "shin"].iter().zip(phases) {
        let cells: Vec<String> = (PHASE_NAMES.iter().zip(errors))
            .map(|(name, e)| {
                let (m, p) = mean_p95(e);
                let over = e.iter().filter(|e| **e > 8.0).count();
                format!("{name} {} {m:.1}/{p:.1} >8: {over}", e.len())
            })
            .collect();
        println!("    {segment}: {}", cells.join(", "));
    }
}

/// Prints the sums over the pairs outside the thigh and shin bounds, per segment and phase.
pub fn print_phase_sums(sums: &PhaseSums) {
    println!(
        "where the thigh and shin miss (pairs outside their bounds; frames, mean°, share over 8°):"
    );
    for (segment, sum) in ["thigh", "shin"].iter().zip(sums) {
        let cells: Vec<String> = (PHASE_NAMES.iter().zip(sum))
            .map(|(name, (n, over, total))| {
                let share = 100.0 * *over as f32 / (*n).max(1) as f32;
                let mean = total / (*n).max(1) as f32;
                format!("{name} {n} {mean:.1}° {share:.0}%")
            })
            .collect();
        println!("  {segment}: {}", cells.join(", "));
    }
}

/// Mean and 95th percentile (NaN of none).
fn mean_p95(v: &[f32]) -> (f32, f32) {
    if v.is_empty() {
        return (f32::NAN, f32::NAN);
    }
    let mut v = v.to_vec();
    v.sort_by(f32::total_cmp);
    let mean = v.iter().sum::<f32>() / v.len() as f32;
    (mean, v[(v.len() * 95 / 100).min(v.len() - 1)])
}
