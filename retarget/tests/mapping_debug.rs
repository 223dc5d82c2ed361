//! Prints a mapping table for a pair of corpus entries named by RIGCAST_PAIR="src,tgt"
//! (a debugging aid; passes trivially when the variable is unset).

use rigcast_retarget::analysis::{analyze, SkeletonView};
use rigcast_retarget::corpus;
use rigcast_retarget::mapping::{auto_map, MapOptions};

#[test]
fn print_pair() {
    let Ok(pair) = std::env::var("RIGCAST_PAIR") else {
        return;
    };
    let (s, t) = pair.split_once(',').unwrap();
    let src = corpus::get(s).unwrap();
    let tgt = corpus::get(t).unwrap();
    let sa = analyze(&SkeletonView::rest(&src.skeleton));
    let ta = analyze(&SkeletonView::rest(&tgt.skeleton));
    let table = auto_map(
        &SkeletonView::rest(&src.skeleton),
        &SkeletonView::rest(&tgt.skeleton),
        &MapOptions::default(),
    );
    for b in tgt.skeleton.bone_ids() {
        let e = table.get(b);
        let src_name = e
            .and_then(|e| e.primary())
            .map(|p| format!("{} [{}]", src.skeleton.name(p.bone), sa.label(p.bone)))
            .unwrap_or_default();
        println!(
            "{:28} {:22} <- {:40} {:6.1} {:?}",
            tgt.skeleton.name(b),
            ta.label(b),
            src_name,
            e.map(|e| e.score).unwrap_or(0.0),
            e.map(|e| e.evidence.clone()).unwrap_or_default()
        );
    }
}
