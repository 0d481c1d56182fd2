//! Species presets for the Weber–Penn generator.
//!
//! Values are chosen so that the generated trees have the dimensions of
//! mature urban trees in the Netherlands (heights and stem diameters as in
//! the national tree registers), in the spirit of the parameter lists of the
//! procedural-tree-generation paper's Appendix A.1 (black oak, silver birch,
//! Lombardy poplar, small pine), adjusted from scene units to metres.

use super::Species;
use super::weber_penn::{CrownShape, LevelParams, TreeParams};

impl TreeParams {
    /// The parameters of a species.
    ///
    /// Ranges over seeds 0–59 (height of the highest node, stem diameter at
    /// 1.3 m, internodes):
    ///
    /// | species | height | DBH | internodes | crown |
    /// |---|---|---|---|---|
    /// | oak | 15–22 m | 0.46–0.71 m | 2,600–5,600 | broad, hemispherical, twisting limbs |
    /// | birch | 14–21 m | 0.23–0.37 m | 1,700–3,000 | slender, drooping twigs |
    /// | poplar | 19–29 m | 0.43–0.71 m | 1,000–1,800 | columnar (Lombardy), steep branches |
    /// | pine | 15–21 m | 0.33–0.52 m | 1,200–2,400 | conical, whorled, strong leader |
    pub fn preset(species: Species) -> TreeParams {
        match species {
            Species::Oak => oak(),
            Species::Birch => birch(),
            Species::Poplar => poplar(),
            Species::Pine => pine(),
        }
    }
}

/// A level with neutral values, to be adjusted per species.
fn level(length: f32, branches: u32, down_angle_deg: f32, internode_m: f32) -> LevelParams {
    LevelParams {
        length,
        length_v: 0.1 * length,
        taper: 1.0,
        base_size: 0.0,
        down_angle_deg,
        down_angle_v_deg: 10.0,
        rotate_deg: 140.0,
        rotate_v_deg: 30.0,
        branches,
        whorl: 1,
        bud_break: 0.9,
        curve_deg: 0.0,
        curve_back_deg: 0.0,
        curve_v_deg: 30.0,
        seg_splits: 0.0,
        split_angle_deg: 30.0,
        split_angle_v_deg: 10.0,
        internode_m,
    }
}

fn oak() -> TreeParams {
    TreeParams {
        shape: CrownShape::Hemispherical,
        scale_m: 17.0,
        scale_v_m: 1.8,
        ratio: 0.018,
        ratio_power: 1.3,
        flare: 0.6,
        attraction_up: 0.4,
        min_radius_m: 0.003,
        levels: vec![
            LevelParams {
                taper: 0.95,
                base_size: 0.22,
                curve_v_deg: 20.0,
                ..level(1.0, 0, 0.0, 0.5)
            },
            LevelParams {
                down_angle_v_deg: -25.0,
                curve_deg: -25.0,
                curve_v_deg: 70.0,
                seg_splits: 0.04,
                split_angle_deg: 35.0,
                ..level(0.55, 32, 55.0, 0.4)
            },
            LevelParams {
                base_size: 0.1,
                curve_deg: -15.0,
                curve_v_deg: 90.0,
                ..level(0.4, 16, 45.0, 0.3)
            },
        ],
    }
}

fn birch() -> TreeParams {
    TreeParams {
        shape: CrownShape::TendFlame,
        scale_m: 15.5,
        scale_v_m: 2.0,
        ratio: 0.0105,
        ratio_power: 1.2,
        flare: 0.4,
        attraction_up: -1.2,
        min_radius_m: 0.002,
        levels: vec![
            LevelParams {
                taper: 0.97,
                base_size: 0.3,
                curve_v_deg: 15.0,
                ..level(1.0, 0, 0.0, 0.5)
            },
            LevelParams {
                down_angle_v_deg: -15.0,
                curve_deg: 35.0,
                curve_v_deg: 40.0,
                ..level(0.33, 40, 45.0, 0.35)
            },
            LevelParams {
                base_size: 0.05,
                curve_v_deg: 40.0,
                ..level(0.5, 14, 35.0, 0.25)
            },
        ],
    }
}

fn poplar() -> TreeParams {
    TreeParams {
        shape: CrownShape::TendFlame,
        scale_m: 22.0,
        scale_v_m: 3.0,
        ratio: 0.013,
        ratio_power: 1.4,
        flare: 0.5,
        attraction_up: 1.0,
        min_radius_m: 0.003,
        levels: vec![
            LevelParams {
                taper: 0.97,
                base_size: 0.08,
                curve_v_deg: 8.0,
                ..level(1.0, 0, 0.0, 0.5)
            },
            LevelParams {
                down_angle_v_deg: 8.0,
                curve_deg: -12.0,
                curve_v_deg: 20.0,
                ..level(0.2, 55, 22.0, 0.4)
            },
            LevelParams {
                base_size: 0.1,
                down_angle_v_deg: 10.0,
                curve_v_deg: 30.0,
                ..level(0.4, 9, 25.0, 0.3)
            },
        ],
    }
}

fn pine() -> TreeParams {
    TreeParams {
        shape: CrownShape::Conical,
        scale_m: 17.5,
        scale_v_m: 2.0,
        ratio: 0.013,
        ratio_power: 1.5,
        flare: 0.3,
        attraction_up: 0.6,
        min_radius_m: 0.003,
        levels: vec![
            LevelParams {
                taper: 0.98,
                base_size: 0.3,
                // A strong, nearly straight leader.
                curve_v_deg: 5.0,
                ..level(1.0, 0, 0.0, 0.5)
            },
            LevelParams {
                whorl: 5,
                rotate_deg: 37.0,
                rotate_v_deg: 15.0,
                down_angle_v_deg: -25.0,
                curve_deg: -10.0,
                curve_v_deg: 25.0,
                bud_break: 0.8,
                ..level(0.32, 14, 75.0, 0.4)
            },
            LevelParams {
                base_size: 0.15,
                curve_v_deg: 30.0,
                ..level(0.35, 12, 50.0, 0.3)
            },
        ],
    }
}
