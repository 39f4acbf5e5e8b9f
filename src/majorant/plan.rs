//! Which pyramid cells the adaptive walk opens: per cell, the *segment price* below which
//! descending pays, computed once at build time by dynamic programming over every level (not
//! root against bricks only), for every extinction and ray direction at once.
//!
//! Cost model, in lookups per unit of ray length divided by the medium's extinction scale σ
//! (so in density units): a segment whose bounds need lookups costs its *lookup density* `L`
//! (its majorant, or 0 when it is empty or of proven constant density), and every segment
//! boundary costs [`super::SEGMENT_COST`] lookups. A ray of unit world direction whose
//! index-space direction is `d` crosses `|d|₁ / (w·2^ℓ)` boundaries of level-ℓ cells per unit
//! length (level-0 cells `w` voxels wide): with the ray's *segment price*
//! `λ = SEGMENT_COST · |d|₁ / (w σ)` that is `λ/2^ℓ` in density units. Opening a level-ℓ cell
//! adds the child boundaries inside it, `λ/2^ℓ`, and replaces its lookup density by the
//! volume mean of its children's best costs (for rays of a fixed direction at uniformly
//! distributed offsets, the expected length inside each child is proportional to its volume):
//!
//! `f_c(λ) = min(L(c), mean over children of f_child(λ) + λ/2^ℓ)`, `f = L` at level 0.
//!
//! Each `f_c` is continuous, piecewise linear and non-decreasing in λ, so the descent term
//! minus `L(c)` is strictly increasing (slope at least `1/2^ℓ`) and crosses zero once: the cell
//! is opened exactly when `λ < λ*(c)`. [`open_prices`] computes every `λ*(c)` exactly, bottom
//! up: a cell's descent term starts at the volume mean of its level-0 lookup densities and its
//! slope drops at the prices where open descendants close (each descendant contributes one such
//! event, so a level holds at most as many events as there are cells below it). A finer grid
//! of the same field only adds levels whose cells stay closed where they do not pay, so the
//! lookups per unit optical depth do not grow with the voxel resolution.

use glam::IVec3;

use super::{Level, LookupModel, MajorantPyramid};

/// The lookup models whose prices are stored per cell ([`LookupModel::Probed`] is
/// [`super::PROBE_COST`] times [`LookupModel::Majorant`]: its prices are that multiple).
pub(super) const PRICED_MODELS: [LookupModel; 2] =
    [LookupModel::Majorant, LookupModel::AboveMinorant];

/// One cell's best cost as a function of the segment price λ: `f(λ) = f0 + ∫₀^λ s(u) du`, the
/// slope `s` starting at `s0` and dropping by `drop` at each event's `price` (to 0 after the
/// last one, where the cell closes).
#[derive(Clone, Copy, Debug, Default)]
struct Cost {
    f0: f64,
    s0: f64,
}

/// A slope drop of a cost function at a price.
#[derive(Clone, Copy, Debug)]
struct Event {
    price: f64,
    drop: f64,
}

/// One level's cost functions: per cell, [`Cost`] and its events (`events[first[i]..first[i + 1]]`,
/// sorted by price).
struct LevelCosts {
    costs: Vec<Cost>,
    first: Vec<usize>,
    events: Vec<Event>,
}

/// The root's best cost as a function of the segment price λ (density units, the model's
/// stored prices): `min(L(root), descent term)`, piecewise linear. The walk compares the
/// lookups opening the root saves along one ray with what preparing the walk costs
/// ([`super::WALK_COST`]; [`super::walk::root_step`]).
#[derive(Clone, Debug, Default)]
pub(super) struct RootCost {
    /// The root's own lookup density (the cost of emitting it whole).
    whole: f32,
    /// Breakpoints `(price, cost, slope)`, by increasing price: on `[price_k, price_k+1)` the
    /// cost is `cost_k + slope_k · (λ − price_k)`. Empty when the root is never opened.
    knots: Vec<[f32; 3]>,
}

impl RootCost {
    /// The root's best cost at segment price `price`.
    #[inline]
    pub(super) fn at(&self, price: f32) -> f32 {
        let k = self.knots.partition_point(|k| k[0] <= price);
        match k.checked_sub(1).and_then(|i| self.knots.get(i)) {
            Some(&[p, f, s]) => (f + s * (price - p)).min(self.whole),
            None => self.whole,
        }
    }

    /// What opening the root saves per unit length at segment price `price` (density units,
    /// ≥ 0).
    #[inline]
    pub(super) fn saving(&self, price: f32) -> f32 {
        (self.whole - self.at(price)).max(0.0)
    }

    /// The largest saving at any price (at price 0), an upper bound of [`Self::saving`].
    #[inline]
    pub(super) fn max_saving(&self) -> f32 {
        self.knots
            .first()
            .map_or(0.0, |k| (self.whole - k[1]).max(0.0))
    }
}

/// Per level and cell, the price below which the cell is opened under `model`
/// (`out[level][cell]`; 0 at level 0 and for cells never worth opening), and the root's cost
/// function.
pub(super) fn open_prices(
    pyramid: &MajorantPyramid,
    model: LookupModel,
) -> (Vec<Vec<f32>>, RootCost) {
    let levels = &pyramid.levels;
    let mut out = Vec::with_capacity(levels.len());
    let Some(level0) = levels.first() else {
        return (out, RootCost::default());
    };
    out.push(vec![0.0f32; level0.cells.len()]);
    let mut below = LevelCosts {
        costs: level0
            .cells
            .iter()
            .map(|b| Cost {
                f0: f64::from(pyramid.lookup_density(b, model)),
                s0: 0.0,
            })
            .collect(),
        first: vec![0; level0.cells.len() + 1],
        events: Vec::new(),
    };
    let mut merged: Vec<Event> = Vec::new();
    for (level, lv) in levels.iter().enumerate().skip(1) {
        let child = &levels[level - 1];
        let own = 1.0 / f64::from(1u32 << level.min(31));
        let n = lv.cells.len();
        let mut prices = vec![0.0f32; n];
        let mut here = LevelCosts {
            costs: vec![Cost::default(); n],
            first: Vec::with_capacity(n + 1),
            events: Vec::new(),
        };
        here.first.push(0);
        for z in 0..lv.dims.z {
            for y in 0..lv.dims.y {
                for x in 0..lv.dims.x {
                    let c = IVec3::new(x, y, z);
                    let i = lv.index(c);
                    let whole = f64::from(pyramid.lookup_density(&lv.cells[i], model));
                    let (mut f0, mut s0) = (0.0, own);
                    merged.clear();
                    for_children(child, c, |j| {
                        let cc = below.costs[j];
                        f0 += cc.f0 / 8.0;
                        s0 += cc.s0 / 8.0;
                        merged.extend(below.events[below.first[j]..below.first[j + 1]].iter().map(
                            |e| Event {
                                price: e.price,
                                drop: e.drop / 8.0,
                            },
                        ));
                    });
                    if f0 < whole {
                        merged.sort_unstable_by(|a, b| a.price.total_cmp(&b.price));
                        // Sweep the descent term up to its crossing with `whole`.
                        let (mut price, mut f, mut s) = (0.0f64, f0, s0);
                        let mut kept = 0;
                        for e in &merged {
                            let at = f + s * (e.price - price);
                            if at >= whole {
                                break;
                            }
                            f = at;
                            price = e.price;
                            s -= e.drop;
                            kept += 1;
                        }
                        // The cell's own boundaries keep the slope at least `own` > 0.
                        let s = s.max(own);
                        let crossing = price + (whole - f) / s;
                        prices[i] = crossing as f32;
                        here.costs[i] = Cost { f0, s0 };
                        here.events.extend_from_slice(&merged[..kept]);
                        here.events.push(Event {
                            price: crossing,
                            drop: s,
                        });
                    } else {
                        here.costs[i] = Cost { f0: whole, s0: 0.0 };
                    }
                    here.first.push(here.events.len());
                }
            }
        }
        // Cells were visited in index order (x fastest), so `first` is indexed by cell.
        out.push(prices);
        below = here;
    }
    (out, root_cost(pyramid, model, &below))
}

/// The root's cost function from the top level's costs (one cell).
fn root_cost(pyramid: &MajorantPyramid, model: LookupModel, top: &LevelCosts) -> RootCost {
    let (Some(root), Some(cost)) = (
        pyramid.levels.last().and_then(|l| l.cells.first()),
        top.costs.first(),
    ) else {
        return RootCost::default();
    };
    let whole = pyramid.lookup_density(root, model);
    let events = top
        .first
        .get(0..2)
        .and_then(|r| top.events.get(r[0]..r[1]))
        .unwrap_or(&[]);
    if events.is_empty() {
        return RootCost {
            whole,
            knots: Vec::new(),
        };
    }
    let mut knots = Vec::with_capacity(events.len() + 1);
    let (mut price, mut f, mut s) = (0.0f64, cost.f0, cost.s0);
    knots.push([0.0, f as f32, s as f32]);
    for e in events {
        f += s * (e.price - price);
        price = e.price;
        s = (s - e.drop).max(0.0);
        knots.push([price as f32, f as f32, s as f32]);
    }
    RootCost { whole, knots }
}

/// Calls `f` with the index of each child of level-(ℓ+1) cell `c` inside `child`'s box
/// (children beyond it hold the background, which needs no lookups).
fn for_children(child: &Level, c: IVec3, mut f: impl FnMut(usize)) {
    for k in 0..8 {
        let cc = c * 2 + IVec3::new(k & 1, (k >> 1) & 1, k >> 2);
        if cc.cmplt(child.dims).all() {
            f(child.index(cc));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::BRICK_DIM;
    use crate::majorant::Bounds;
    use crate::sampling::Rng;
    use glam::{DAffine3, DVec3};

    /// A pyramid over `n`³ bricks with bounds `field(brick key)`.
    fn pyramid(n: i32, field: impl Fn(IVec3) -> Bounds) -> MajorantPyramid {
        let scale = DAffine3::from_scale(DVec3::splat(f64::from(n * BRICK_DIM)));
        MajorantPyramid::from_brick_bounds(IVec3::ZERO, IVec3::splat(n - 1), 0.0, scale, field)
            .unwrap_or_else(|e| unreachable!("{e}"))
    }

    /// The dynamic programme at one price, by brute force: per level, per cell, open or not,
    /// and the root's best cost.
    fn brute_force(p: &MajorantPyramid, price: f64, model: LookupModel) -> (Vec<Vec<bool>>, f64) {
        let mut open = Vec::new();
        let mut best: Vec<f64> = Vec::new();
        for (level, lv) in p.levels.iter().enumerate() {
            let whole: Vec<f64> = lv
                .cells
                .iter()
                .map(|b| f64::from(p.lookup_density(b, model)))
                .collect();
            if level == 0 {
                open.push(vec![false; whole.len()]);
                best = whole;
                continue;
            }
            let child = &p.levels[level - 1];
            let mut here = whole.clone();
            let mut opens = vec![false; whole.len()];
            for z in 0..lv.dims.z {
                for y in 0..lv.dims.y {
                    for x in 0..lv.dims.x {
                        let c = IVec3::new(x, y, z);
                        let i = lv.index(c);
                        let mut sum = 0.0;
                        for_children(child, c, |j| sum += best[j]);
                        let descend = sum / 8.0 + price / f64::from(1u32 << level);
                        if descend < whole[i] {
                            here[i] = descend;
                            opens[i] = true;
                        }
                    }
                }
            }
            open.push(opens);
            best = here;
        }
        (open, best.first().copied().unwrap_or(0.0))
    }

    #[test]
    fn prices_reproduce_the_dynamic_programme_at_every_price() {
        // Random bounds with empty and constant bricks, over 12³ bricks (5 levels, ragged
        // boxes at the coarser ones).
        let mut rng = Rng::new(11, 2);
        let mut table = Vec::new();
        for _ in 0..12 * 12 * 12 {
            let kind = rng.next_u32() % 5;
            let hi = rng.next_f32() * 4.0;
            let lo = hi * rng.next_f32();
            table.push(match kind {
                0 => Bounds::constant(0.0),
                1 => Bounds::constant(hi),
                _ => Bounds {
                    min: lo,
                    max: hi,
                    mean: 0.5 * (lo + hi),
                },
            });
        }
        let p = pyramid(12, |k| table[((k.z * 12 + k.y) * 12 + k.x) as usize]);
        for model in PRICED_MODELS {
            let (prices, _) = open_prices(&p, model);
            let (mut opened, mut checked) = (0usize, 0usize);
            for price in [1e-4, 1e-2, 0.05, 0.1, 0.3, 0.7, 1.5, 4.0, 10.0, 100.0] {
                let (open, _) = brute_force(&p, price, model);
                for (level, cells) in open.iter().enumerate() {
                    for (i, &o) in cells.iter().enumerate() {
                        let star = f64::from(prices[level][i]);
                        // Skip near-ties (the price is stored in f32).
                        if (star - price).abs() <= 1e-5 * price {
                            continue;
                        }
                        assert_eq!(
                            o,
                            price < star,
                            "{model:?} level {level} cell {i}: price {price}, λ* {star}"
                        );
                        opened += usize::from(o);
                        checked += 1;
                    }
                }
            }
            assert!(opened > 100 && opened < checked, "{opened} of {checked}");
        }
    }

    #[test]
    fn the_root_cost_is_the_dynamic_programme_at_every_price() {
        // A blob of random bounds in a sparse box (the root worth opening at low prices, not
        // at high ones), over 12³ bricks.
        let mut rng = Rng::new(5, 3);
        let mut table = Vec::new();
        for i in 0..12 * 12 * 12 {
            let k = IVec3::new(i % 12, (i / 12) % 12, i / 144);
            let inside = (k.as_vec3() - 5.5).length() < 4.0;
            let hi = if inside {
                1.0 + rng.next_f32() * 3.0
            } else {
                0.02 * rng.next_f32()
            };
            table.push(Bounds {
                min: 0.0,
                max: hi,
                mean: 0.5 * hi,
            });
        }
        let p = pyramid(12, |k| table[((k.z * 12 + k.y) * 12 + k.x) as usize]);
        for model in PRICED_MODELS {
            let (_, root) = open_prices(&p, model);
            let whole = f64::from(root.whole);
            let mut saved = 0;
            for price in [0.0, 1e-4, 1e-2, 0.05, 0.1, 0.3, 0.7, 1.5, 4.0, 10.0, 100.0] {
                let (_, best) = brute_force(&p, price, model);
                let cost = f64::from(root.at(price as f32));
                assert!(
                    (cost - best).abs() <= 1e-4 * whole,
                    "{model:?} at {price}: {cost} against {best}"
                );
                let saving = f64::from(root.saving(price as f32));
                assert!(saving >= 0.0 && saving <= f64::from(root.max_saving()) + 1e-6);
                saved += usize::from(saving > 1e-3 * whole);
            }
            assert!(
                saved > 2 && saved < 11,
                "{model:?}: saves at {saved} prices"
            );
        }
    }

    #[test]
    fn a_uniform_field_is_never_split() {
        // Equal majorants everywhere: splitting only adds boundaries.
        let p = pyramid(8, |_| Bounds {
            min: 0.0,
            max: 3.0,
            mean: 1.0,
        });
        for prices in open_prices(&p, LookupModel::Majorant).0 {
            assert!(prices.iter().all(|&x| x == 0.0));
        }
    }

    #[test]
    fn a_blob_opens_the_root_only_when_segments_are_cheap() {
        // One dense blob in a sparse box: the root pays to open at a low price (thick
        // medium), not at a high one (thin medium).
        let p = pyramid(16, |k| {
            let c = (k.as_dvec3() + 0.5) / 16.0;
            let v = if (c - 0.5).length() < 0.15 {
                10.0
            } else {
                0.01
            };
            Bounds {
                min: 0.0,
                max: v,
                mean: 0.5 * v,
            }
        });
        let (prices, _) = open_prices(&p, LookupModel::Majorant);
        let root = prices.last().map_or(0.0, |l| l[0]);
        assert!(root > 1e-3 && root < 1e3, "root price {root}");
        let opened_at_small = prices.iter().flatten().filter(|&&x| x > 1e-3).count();
        assert!(
            opened_at_small > 8,
            "{opened_at_small} cells open at price 1e-3"
        );
    }
}
