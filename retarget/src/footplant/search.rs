//! The foot lock's one-dimensional searches (the body's height, a foot's lift and its move
//! over the ground): each minimises a smooth cost of one length.

/// Where in `[lo, hi]` `cost` is least: first `scan` evenly spaced samples, as the cost need
/// not have one minimum over the whole range (with fewer than 2, the whole range is taken to
/// have one), then `steps` golden-section steps between the best sample's neighbours (the
/// bracket shrinks 0.618 a step).
pub(crate) fn least_between(
    cost: impl Fn(f32) -> f32,
    lo: f32,
    hi: f32,
    scan: usize,
    steps: usize,
) -> f32 {
    let (mut a, mut b) = if scan >= 2 {
        let step = (hi - lo) / (scan - 1) as f32;
        let at = |k: usize| lo + step * k as f32;
        // Each sample's cost once (a comparison sort would ask for most of them twice); the
        // first of equal least costs, as `min_by` gives.
        let mut best = (0, f32::NAN);
        for k in 0..scan {
            let c = cost(at(k));
            if k == 0 || c.total_cmp(&best.1).is_lt() {
                best = (k, c);
            }
        }
        let best = best.0;
        (at(best.saturating_sub(1)), at((best + 1).min(scan - 1)))
    } else {
        (lo, hi)
    };
    let k = 0.5 * (5f32.sqrt() - 1.0);
    let (mut c, mut d) = (b - k * (b - a), a + k * (b - a));
    let (mut fc, mut fd) = (cost(c), cost(d));
    for _ in 0..steps {
        if fc < fd {
            (b, d, fd) = (d, c, fc);
            c = b - k * (b - a);
            fc = cost(c);
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + k * (b - a);
            fd = cost(d);
        }
    }
    0.5 * (a + b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_least_of_a_parabola_and_the_lower_of_two_valleys() {
        let x = least_between(|x| (x - 0.3) * (x - 0.3), -1.0, 1.0, 0, 40);
        assert!((x - 0.3).abs() < 1e-4, "{x}");
        // Two valleys, the deeper at 0.7: golden steps alone over the range may end in
        // either; the scan picks the deeper.
        let two = |x: f32| ((x + 0.6) * (x + 0.6)).min((x - 0.7) * (x - 0.7) - 0.1);
        let x = least_between(two, -1.0, 1.0, 9, 40);
        assert!((x - 0.7).abs() < 1e-3, "{x}");
    }
}
