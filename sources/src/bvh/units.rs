//! Which unit a BVH file is written in, when the user does not say: the one that makes its
//! figure's standing height most like a person's, with how clearly it beats the others.

/// Candidate units, metres per unit: metres, decimetres (MakeHuman's own unit), CMU's
/// "inches / 0.45", inches, centimetres, millimetres.
pub const UNIT_CANDIDATES: [f32; 6] = [1.0, 0.1, 0.056444, 0.0254, 0.01, 0.001];

/// A person's standing height, metres.
const PERSON_HEIGHT_M: f32 = 1.7;

/// Spread of a person-sized figure's height, natural log: about a factor 1.28 either way
/// covers children, tall adults and stylised characters.
const PERSON_LOG_SPREAD: f32 = 0.25;

/// A guessed unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnitGuess {
    /// Metres per file unit.
    pub scale: f32,
    /// 0..1: the chosen unit's share of the evidence among all candidates (heights spread
    /// log-normally about a person's). 0.5 is a figure halfway between two units; it says
    /// which unit, not whether the figure is a person at all.
    pub confidence: f32,
}

/// Guesses metres per file unit from a figure's standing height in file units (see
/// [`crate::stature`]): the candidate unit under which it is most like a person. A figure that
/// is not person-sized may need an explicit scale.
pub fn guess_unit(height_in_file_units: f32) -> UnitGuess {
    if !(height_in_file_units.is_finite() && height_in_file_units > 0.0) {
        return UnitGuess {
            scale: 1.0,
            confidence: 0.0,
        };
    }
    // Squared distance, in spreads, of the height in each unit from a person's.
    let z2 = |s: f32| {
        let z = (height_in_file_units * s / PERSON_HEIGHT_M).ln() / PERSON_LOG_SPREAD;
        z * z
    };
    let best = UNIT_CANDIDATES
        .into_iter()
        .min_by(|a, b| z2(*a).total_cmp(&z2(*b)))
        .unwrap_or(1.0);
    // The posterior of the best unit, computed relative to it so no term underflows.
    let total: f32 = UNIT_CANDIDATES
        .iter()
        .map(|&s| (-0.5 * (z2(s) - z2(best))).exp())
        .sum();
    UnitGuess {
        scale: best,
        confidence: 1.0 / total,
    }
}

/// Units a person may name for a BVH file, metres per unit (`rigcast … --unit`).
const NAMED_UNITS: [(&str, f32); 8] = [
    ("m", 1.0),
    ("dm", 0.1),
    ("cm", 0.01),
    ("mm", 0.001),
    ("in", 0.0254),
    ("inch", 0.0254),
    ("ft", 0.3048),
    ("cmu", 0.056444),
];

/// Reads a unit a person gives for a BVH file: a name (`m`, `dm`, `cm`, `mm`, `in`, `ft`, or
/// `cmu` for CMU's "inches / 0.45") or metres per file unit as a number (`0.01`). The error
/// says what is accepted.
pub fn parse_unit(text: &str) -> Result<f32, String> {
    let t = text.trim().to_ascii_lowercase();
    if let Some((_, s)) = NAMED_UNITS.iter().find(|(n, _)| *n == t) {
        return Ok(*s);
    }
    match t.parse::<f32>() {
        Ok(s) if s.is_finite() && s > 0.0 && s <= MAX_GIVEN_SCALE => Ok(s),
        _ => Err(format!(
            "`{text}` is not a unit: give m, dm, cm, mm, in, ft or cmu, or metres per file unit \
             as a positive number up to {MAX_GIVEN_SCALE} (0.01 for centimetres)"
        )),
    }
}

/// Largest metres-per-unit a person may give: a kilometre per unit is already no body.
const MAX_GIVEN_SCALE: f32 = 1000.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_person_sized_height_picks_its_unit_surely() {
        for (height, unit) in [(1.8, 1.0), (175.0, 0.01), (1750.0, 0.001), (67.0, 0.0254)] {
            let g = guess_unit(height);
            assert_eq!(g.scale, unit, "{height}");
            assert!(g.confidence > 0.9, "{height}: {}", g.confidence);
        }
    }

    /// Halfway (in ratio) between centimetres and inches the two are equally likely.
    #[test]
    fn a_height_between_two_units_is_unsure() {
        let between = PERSON_HEIGHT_M / (0.01f32 * 0.0254).sqrt();
        let g = guess_unit(between * 1.001);
        assert!((g.confidence - 0.5).abs() < 0.02, "{}", g.confidence);
        assert_eq!(guess_unit(0.0).confidence, 0.0);
        assert_eq!(guess_unit(f32::NAN).scale, 1.0);
    }

    #[test]
    fn units_by_name_or_number() {
        assert_eq!(parse_unit("cm"), Ok(0.01));
        assert_eq!(parse_unit(" IN "), Ok(0.0254));
        assert_eq!(parse_unit("0.001"), Ok(0.001));
        for bad in ["", "furlong", "0", "-1", "nan", "inf", "1e9"] {
            let e = parse_unit(bad).unwrap_err();
            assert!(e.contains("cm"), "{bad}: {e}");
        }
    }
}
