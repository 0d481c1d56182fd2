//! Fuzzes the skeleton PLY reader (`silva::Skeleton::from_ply`): silva's
//! binary files and AdTree's ascii ones. Any input must give a skeleton or a
//! typed error, never a panic, a hang or an unbounded allocation; what is
//! read is written again and must read back as the same tree.
#![no_main]

use libfuzzer_sys::fuzz_target;
use silva::Skeleton;

fuzz_target!(|data: &[u8]| {
    let Ok(tree) = Skeleton::from_ply(data) else {
        return;
    };
    let back = Skeleton::from_ply(&tree.to_ply()).expect("silva reads the PLY it writes");
    assert_eq!(back.len(), tree.len());
    assert_eq!(back.anchor().crs, tree.anchor().crs);
    for (a, b) in tree.ids().zip(back.ids()) {
        assert_eq!(back.parent(b), tree.parent(a));
        assert_eq!(back.children(b), tree.children(a));
        assert_eq!(back.radius(b), tree.radius(a));
        // Absolute coordinates are doubles: exact up to their own rounding.
        let p = tree.absolute_position(a);
        let d = (back.absolute_position(b) - p).length();
        assert!(d <= 1e-6 * (1.0 + p.abs().max_element()), "node {a:?} moved {d}");
    }
});
