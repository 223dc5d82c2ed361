//! Name evidence: bone names normalised into canonical tokens.
//!
//! Names are one signal among several (they are absent or meaningless on many rigs), so this
//! module only *normalises*: it strips rig prefixes (`mixamorig:`, `DEF-`, `ORG-`, `MCH-`,
//! `CC_Base_`, `Bip01`…), splits CamelCase / snake_case / dotted names, pulls out every common
//! left/right marker (`Left`, `_l`, `.L`, `lThigh`…) and folds synonyms (thigh / upleg / upperleg
//! → `thigh`). The mapper compares the resulting token sets; the analysis uses the side marker
//! only to resolve the one ambiguity geometry cannot (which way the character faces when its
//! feet and head give no cue).

use super::Side;

/// A normalised bone name.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct NameInfo {
    /// Side marker found in the name, if any.
    pub side: Option<Side>,
    /// Canonical tokens (lower case, synonyms folded), side markers and prefixes removed.
    pub tokens: Vec<String>,
    /// The name carries a helper marker (`ORG-`, `MCH-`, `twist`, `ik`, `end`, `nub`…).
    pub helper: bool,
    /// Trailing numbers in the name (e.g. `Spine2` → 2, `DEF-spine.003` → 3).
    pub number: Option<u32>,
}

/// Prefixes stripped before tokenising (compared case-insensitively).
const PREFIXES: &[&str] = &[
    "mixamorig:",
    "mixamorig_",
    "mixamorig",
    "def-",
    "org-",
    "mch-",
    "cc_base_",
    "bip01_",
    "bip01 ",
    "bip001_",
    "bip001 ",
    "j_bip_",
    "j_",
    "b_",
    "m_avg_",
];

/// Japanese (MMD) part names, longest first: (name part, canonical token). Sides are 左 / 右.
const JAPANESE: &[(&str, &str)] = &[
    ("上半身", "chest"),
    ("下半身", "pelvis"),
    ("センター", "root"),
    ("足首", "foot"),
    ("手首", "hand"),
    ("つま先", "toe"),
    ("親指", "thumb"),
    ("人差指", "index"),
    ("人指", "index"),
    ("中指", "middle"),
    ("薬指", "ring"),
    ("小指", "little"),
    ("ひざ", "shin"),
    ("ひじ", "forearm"),
    ("肩", "clavicle"),
    ("腕", "upperarm"),
    ("足", "thigh"),
    ("首", "neck"),
    ("頭", "head"),
    ("目", "eye"),
    ("捩", "twist"),
    ("ＩＫ", "ik"),
];

/// Replaces Japanese part names by canonical ASCII words and pulls out 左 / 右.
fn japanese(name: &str) -> (String, Option<Side>) {
    let mut side = None;
    let mut out = String::with_capacity(name.len());
    let mut rest = name;
    'scan: while let Some(c) = rest.chars().next() {
        match c {
            '左' => side = side.or(Some(Side::Left)),
            '右' => side = side.or(Some(Side::Right)),
            _ => {
                for (jp, canon) in JAPANESE {
                    if let Some(r) = rest.strip_prefix(jp) {
                        out.push(' ');
                        out.push_str(canon);
                        out.push(' ');
                        rest = r;
                        continue 'scan;
                    }
                }
                out.push(c);
            }
        }
        rest = &rest[c.len_utf8()..];
    }
    (out, side)
}

/// Synonym folding: (token seen in names, canonical token).
const SYNONYMS: &[(&str, &str)] = &[
    ("upleg", "thigh"),
    ("upperleg", "thigh"),
    ("hip", "thigh"),
    ("hips", "pelvis"),
    ("pelvis", "pelvis"),
    ("root", "root"),
    ("shin", "shin"),
    ("calf", "shin"),
    ("knee", "shin"),
    ("lowerleg", "shin"),
    ("leg", "shin"),
    ("ankle", "foot"),
    ("foot", "foot"),
    ("toe", "toe"),
    ("toes", "toe"),
    ("toebase", "toe"),
    ("ball", "toe"),
    ("collar", "clavicle"),
    ("clavicle", "clavicle"),
    ("shoulder", "clavicle"),
    ("upperarm", "upperarm"),
    ("uparm", "upperarm"),
    ("arm", "upperarm"),
    ("shldr", "upperarm"),
    ("humerus", "upperarm"),
    ("forearm", "forearm"),
    ("lowerarm", "forearm"),
    ("elbow", "forearm"),
    ("wrist", "hand"),
    ("hand", "hand"),
    ("palm", "hand"),
    ("abdomen", "spine"),
    ("lowerback", "spine"),
    ("back", "spine"),
    ("spine", "spine"),
    ("chest", "chest"),
    ("upperchest", "chest"),
    ("torso", "spine"),
    ("neck", "neck"),
    ("lowerneck", "neck"),
    ("head", "head"),
    ("skull", "head"),
    ("jaw", "jaw"),
    ("eye", "eye"),
    ("tail", "tail"),
    ("wing", "wing"),
    ("thumb", "thumb"),
    ("index", "index"),
    ("middle", "middle"),
    ("mid", "middle"),
    ("ring", "ring"),
    ("pinky", "little"),
    ("little", "little"),
    ("fingers", "finger"),
    ("finger", "finger"),
];

/// Tokens that mark helper bones (twist, IK, mechanism, end sites).
const HELPER_TOKENS: &[&str] = &[
    "twist", "roll", "ik", "mch", "org", "end", "nub", "tip", "site", "helper", "target", "pole",
];

/// Splits a raw name into lower-case words: CamelCase, snake_case, dots, dashes, colons,
/// spaces and letter/digit boundaries all separate words.
pub fn split_words(name: &str) -> Vec<String> {
    let mut words = Vec::new();
    let mut cur = String::new();
    let chars: Vec<char> = name.chars().collect();
    for (i, &c) in chars.iter().enumerate() {
        if !c.is_alphanumeric() {
            if !cur.is_empty() {
                words.push(std::mem::take(&mut cur));
            }
            continue;
        }
        if let Some(&prev) = cur.chars().last().as_ref() {
            let lower_to_upper = prev.is_lowercase() && c.is_uppercase();
            // "HTMLParser"-style runs: split before the last capital of a run.
            let acronym_end = prev.is_uppercase()
                && c.is_uppercase()
                && chars.get(i + 1).is_some_and(|n| n.is_lowercase());
            let digit_edge = prev.is_ascii_digit() != c.is_ascii_digit();
            if lower_to_upper || acronym_end || digit_edge {
                words.push(std::mem::take(&mut cur));
            }
        }
        cur.push(c);
    }
    if !cur.is_empty() {
        words.push(cur);
    }
    words.into_iter().map(|w| w.to_lowercase()).collect()
}

/// Normalises one bone name.
pub fn normalize(name: &str) -> NameInfo {
    let (ascii, jp_side) = if name.is_ascii() {
        (String::new(), None)
    } else {
        japanese(name)
    };
    let rest = if name.is_ascii() {
        name.trim()
    } else {
        ascii.trim()
    };
    let (rest, mut helper) = strip_prefix(rest);
    let (rest, side) = side_markers(rest, jp_side);
    let mut info = tokenize(&split_words(rest), side);
    helper |= info.helper;
    info.helper = helper;
    info
}

/// Drops one known rig prefix (`mixamorig:`, `DEF-`, `ORG-`…); `ORG-`/`MCH-` mark helpers.
fn strip_prefix(rest: &str) -> (&str, bool) {
    let lower = rest.to_lowercase();
    for p in PREFIXES {
        if lower.starts_with(p) {
            return (&rest[p.len()..], *p == "org-" || *p == "mch-");
        }
    }
    (rest, false)
}

/// Side markers a word split would lose: a Daz/Poser `lThigh` / `rShldr` prefix (one
/// lower-case l/r before a capital), a `.L` / `_l` / ` L` / `-l` suffix, or such a marker in
/// the middle (`_l_`, `.L.001`: UE twist bones, Rigify segments). `side` (a side already
/// known, from Japanese) wins over them.
fn side_markers(mut rest: &str, mut side: Option<Side>) -> (&str, Option<Side>) {
    let mut chars = rest.chars();
    if let (Some(c0), Some(c1)) = (chars.next(), chars.next()) {
        if (c0 == 'l' || c0 == 'r') && c1.is_uppercase() {
            side = Some(if c0 == 'l' { Side::Left } else { Side::Right });
            rest = &rest[1..];
        }
    }
    let lower = rest.to_lowercase();
    // A separator then the side letter: `.L`, `_r`, ` L`, `-R`.
    let suffixes = ['.', '_', ' ', '-']
        .into_iter()
        .flat_map(|sep| [([sep, 'l'], Side::Left), ([sep, 'r'], Side::Right)]);
    for (pair, s) in suffixes {
        let suf: String = pair.iter().collect();
        let suf = suf.as_str();
        if lower.ends_with(suf) {
            return (&rest[..rest.len() - 2], side.or(Some(s)));
        }
        let (mid, mid2) = (format!("{suf}."), format!("{suf}_"));
        if lower.contains(&mid) || lower.contains(&mid2) {
            side = side.or(Some(s));
        }
    }
    (rest, side)
}

/// Canonical tokens of a name's words: numbers become the name's number, side words its side,
/// vertebra names (`L5`, `T8`, `C7`) spine or neck, two-word compounds one token, synonyms
/// their canonical word; helper words mark a helper.
fn tokenize(words: &[String], mut side: Option<Side>) -> NameInfo {
    let (mut tokens, mut number, mut helper) = (Vec::new(), None, false);
    let mut i = 0;
    while i < words.len() {
        let w = words[i].as_str();
        if let Ok(n) = w.parse::<u32>() {
            number = Some(n);
            i += 1;
            continue;
        }
        // Vertebrae (Xsens MVN `L5`, `T8`, `C7`, the whole name): a spine or neck bone, not
        // a side marker (`upper_arm.L.001` keeps its side).
        if let Some((kind, n)) = vertebra(words, i) {
            tokens.push(kind.to_string());
            number = Some(n);
            i += 2;
            continue;
        }
        if let Some(s) = side_word(w) {
            side = side.or(Some(s));
            i += 1;
            continue;
        }
        // Join two-word compounds ("up leg", "fore arm", "upper arm", "toe base").
        if let Some(canon) = words
            .get(i + 1)
            .and_then(|next| synonym(&format!("{w}{next}")))
        {
            tokens.push(canon.to_string());
            i += 2;
            continue;
        }
        helper |= HELPER_TOKENS.contains(&w);
        tokens.push(synonym(w).unwrap_or(w).to_string());
        i += 1;
    }
    NameInfo {
        side,
        tokens,
        helper,
        number,
    }
}

/// `L5`, `T8` (spine) or `C7` (neck) as the whole two-word name, from word `i`.
fn vertebra(words: &[String], i: usize) -> Option<(&'static str, u32)> {
    if i != 0 || words.len() != 2 {
        return None;
    }
    let kind = match words[i].as_str() {
        "l" | "t" => "spine",
        "c" => "neck",
        _ => return None,
    };
    Some((kind, words.get(i + 1)?.parse::<u32>().ok()?))
}

/// The side a whole word names (`left`, `r`, `rgt`…).
fn side_word(w: &str) -> Option<Side> {
    match w {
        "left" | "l" | "lft" => Some(Side::Left),
        "right" | "r" | "rt" | "rgt" => Some(Side::Right),
        _ => None,
    }
}

/// The canonical word for `w`, when it is a known synonym.
fn synonym(w: &str) -> Option<&'static str> {
    SYNONYMS.iter().find(|(k, _)| *k == w).map(|&(_, c)| c)
}

/// Similarity of two normalised names in 0..=1 (Jaccard over tokens; side ignored).
pub fn similarity(a: &NameInfo, b: &NameInfo) -> f32 {
    if a.tokens.is_empty() || b.tokens.is_empty() {
        return 0.0;
    }
    let common = a.tokens.iter().filter(|t| b.tokens.contains(t)).count();
    let union = a.tokens.len() + b.tokens.len() - common;
    let mut s = common as f32 / union.max(1) as f32;
    if s > 0.0 && a.number == b.number {
        s = (s + 0.1).min(1.0);
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `name` normalizes to `side` and the one token `token`.
    fn assert_side_and_token(name: &str, side: Side, token: &str) {
        let n = normalize(name);
        assert_eq!(
            (n.side, n.tokens),
            (Some(side), vec![token.to_string()]),
            "{name}"
        );
    }

    #[test]
    fn sides_and_prefixes() {
        for (name, side, token) in [
            ("mixamorig:LeftUpLeg", Side::Left, "thigh"),
            ("lThigh", Side::Left, "thigh"),
            ("RightForeArm", Side::Right, "forearm"),
        ] {
            assert_side_and_token(name, side, token);
        }
        let n = normalize("DEF-upper_arm.L.001");
        assert_eq!(n.side, Some(Side::Left));
        assert_eq!(n.tokens, vec!["upperarm"]);
        assert_eq!(n.number, Some(1));
        let n = normalize("upperarm_twist_01_r");
        assert_eq!(n.side, Some(Side::Right));
        assert!(n.helper);
        assert_eq!(normalize("calf_l").tokens, vec!["shin"]);
        assert_eq!(normalize("Spine").side, None);
        assert_eq!(normalize("j12").tokens, vec!["j"]);
    }

    #[test]
    fn conventions_people_use() {
        // Xsens MVN vertebrae are spine bones, not left-side bones.
        let n = normalize("L5");
        assert_eq!(
            (n.side, n.tokens.clone(), n.number),
            (None, vec!["spine".to_string()], Some(5))
        );
        assert_eq!(normalize("T8").tokens, vec!["spine"]);
        // 3ds Max Biped, SMPL, Character Creator, RobotExpressive (no separator), and MMD
        // (Japanese): 左足 is the left thigh, 右ひじ the right forearm.
        for (name, side, token) in [
            ("Bip01 L Thigh", Side::Left, "thigh"),
            ("m_avg_R_Knee", Side::Right, "shin"),
            ("CC_Base_L_Upperarm", Side::Left, "upperarm"),
            ("UpperArmL", Side::Left, "upperarm"),
            ("左足", Side::Left, "thigh"),
            ("右ひじ", Side::Right, "forearm"),
        ] {
            assert_side_and_token(name, side, token);
        }
        // Kinect: side word at the end, a tip is an end marker.
        let n = normalize("HandTipLeft");
        assert_eq!(n.side, Some(Side::Left));
        assert!(n.helper);
        // MMD: 左足首 is the left foot, 上半身 the chest.
        assert_eq!(normalize("左足首").tokens, vec!["foot"]);
        assert_eq!(normalize("上半身").tokens, vec!["chest"]);
        assert!(normalize("左足ＩＫ").helper);
    }

    #[test]
    fn splitting() {
        assert_eq!(
            split_words("LeftHandIndex1"),
            vec!["left", "hand", "index", "1"]
        );
        assert_eq!(split_words("spine_01"), vec!["spine", "01"]);
        assert!(similarity(&normalize("LeftUpLeg"), &normalize("thigh_l")) > 0.9);
        assert_eq!(similarity(&normalize("j3"), &normalize("thigh_l")), 0.0);
    }
}
