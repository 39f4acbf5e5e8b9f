//! Which pyramid cells the adaptive walk opens, decided once per medium extinction by dynamic
//! programming over every level (not root against bricks only).
//!
//! Cost model, in lookups per unit of ray length, divided by the medium's extinction scale σ
//! (so in density units): a segment whose bounds need lookups costs its *lookup density* `L`
//! (its majorant, or 0 when it is empty or of proven constant density), and every segment
//! boundary costs [`SEGMENT_COST`] lookups. A ray crosses about `|d|₁ / (w·2^ℓ)` boundaries of
//! level-ℓ cells per unit length (`d` its index-space direction, level-0 cells `w` voxels
//! wide); with `λ = SEGMENT_COST · ⟨|d|₁⟩ / (wσ)` (⟨·⟩ over directions) that is `λ/2^ℓ` in
//! density units. Opening a level-ℓ cell adds the child boundaries inside it, `λ/2^ℓ`, and replaces its
//! lookup density by the mean of its children's best costs:
//!
//! `best(c) = min(L(c), mean over children of best(child) + λ/2^ℓ)`, `best = L` at level 0,
//!
//! and the walk opens `c` exactly where the second term is smaller. A finer grid of the same
//! field only adds levels whose cells the plan leaves closed where they do not pay, so the
//! lookups per unit optical depth do not grow with the voxel resolution.

use glam::{DAffine3, DVec3, IVec3};

use super::{LookupModel, MajorantPyramid, SEGMENT_COST};

/// The cells the adaptive walk opens for one extinction scale.
#[derive(Clone, Debug)]
pub(crate) struct WalkPlan {
    /// The extinction per unit density the plan was made for.
    pub sigma: f32,
    /// The tracker's lookup cost the plan was made for.
    pub model: LookupModel,
    /// Per level, per cell: open it (descend) or emit it whole.
    pub open: Vec<Vec<bool>>,
}

/// Mean of `|M d|₁` over unit directions `d` (a Fibonacci sphere of 256 points): the index-space
/// length of the ray parameter's unit step, summed over the axes.
fn mean_l1_step(world_to_index: &DAffine3) -> f64 {
    let n = 256;
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let mut sum = 0.0;
    for k in 0..n {
        let z = 1.0 - (2.0 * k as f64 + 1.0) / n as f64;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = golden * k as f64;
        let d = DVec3::new(r * phi.cos(), r * phi.sin(), z);
        sum += world_to_index.transform_vector3(d).abs().element_sum();
    }
    sum / n as f64
}

impl WalkPlan {
    /// The plan for a medium whose extinction is `sigma` per unit density.
    pub(crate) fn new(pyramid: &MajorantPyramid, sigma: f32, model: LookupModel) -> Self {
        let lambda = SEGMENT_COST * mean_l1_step(&pyramid.world_to_index)
            / (f64::from(pyramid.finest_cell_voxels()) * f64::from(sigma));
        let mut open: Vec<Vec<bool>> = Vec::with_capacity(pyramid.levels.len());
        let mut best_below: Vec<f64> = Vec::new();
        for (level, lv) in pyramid.levels.iter().enumerate() {
            let whole: Vec<f64> = lv
                .cells
                .iter()
                .map(|b| f64::from(pyramid.lookup_density(b, model)))
                .collect();
            if level == 0 {
                open.push(vec![false; whole.len()]);
                best_below = whole;
                continue;
            }
            let child = &pyramid.levels[level - 1];
            let split = lambda / f64::from(1u32 << level.min(31));
            let mut best = vec![0.0; whole.len()];
            let mut opens = vec![false; whole.len()];
            for z in 0..lv.dims.z {
                for y in 0..lv.dims.y {
                    for x in 0..lv.dims.x {
                        let c = IVec3::new(x, y, z);
                        let i = lv.index(c);
                        let mut sum = 0.0;
                        for k in 0..8 {
                            let cc = c * 2 + IVec3::new(k >> 2, (k >> 1) & 1, k & 1);
                            // Children beyond the child level's box hold the background, which
                            // needs no lookups.
                            if cc.cmplt(child.dims).all() {
                                sum += best_below[child.index(cc)];
                            }
                        }
                        let descend = sum / 8.0 + split;
                        if descend < whole[i] {
                            best[i] = descend;
                            opens[i] = true;
                        } else {
                            best[i] = whole[i];
                        }
                    }
                }
            }
            open.push(opens);
            best_below = best;
        }
        WalkPlan { sigma, model, open }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::BRICK_DIM;
    use crate::majorant::Bounds;

    /// A pyramid over `n`³ bricks whose brick majorants are `field(brick centre)`.
    fn pyramid(n: i32, field: impl Fn(DVec3) -> f32) -> MajorantPyramid {
        let scale = DAffine3::from_scale(DVec3::splat(f64::from(n * BRICK_DIM)));
        MajorantPyramid::from_brick_bounds(IVec3::ZERO, IVec3::splat(n - 1), 0.0, scale, |k| {
            let c = (k.as_dvec3() + 0.5) / f64::from(n);
            let v = field(c);
            Bounds {
                min: 0.0,
                max: v,
                mean: 0.5 * v,
            }
        })
        .unwrap_or_else(|e| unreachable!("{e}"))
    }

    #[test]
    fn optically_thin_media_stay_at_the_root_and_thick_ones_descend() {
        // One dense blob in a sparse box: at σ = 1e-3 no split pays, at σ = 1e4 the empty
        // and thin cells are separated from the blob.
        let p = pyramid(16, |c| {
            if (c - 0.5).length() < 0.15 {
                10.0
            } else {
                0.01
            }
        });
        let top = p.levels.len() - 1;
        let thin = WalkPlan::new(&p, 1e-3, LookupModel::Majorant);
        assert!(!thin.open[top][0], "a thin medium should not open the root");
        let thick = WalkPlan::new(&p, 1e4, LookupModel::Majorant);
        assert!(thick.open[top][0], "a thick medium should open the root");
        let opened: usize = thick.open.iter().flatten().filter(|&&o| o).count();
        assert!(opened > 8, "{opened} cells opened");
    }

    #[test]
    fn a_uniform_field_is_never_split() {
        // Equal majorants everywhere: splitting only adds boundaries.
        let p = pyramid(8, |_| 3.0);
        let plan = WalkPlan::new(&p, 1e6, LookupModel::Majorant);
        assert!(plan.open.iter().flatten().all(|&o| !o));
    }
}
