//! The specular manifold walk for one refractive interface (Hanika, Droske and Fascione 2015,
//! "Manifold next event estimation", §4–5; docs/references.md §5.1–5.3): from a vertex `x0`
//! on one side of a smooth dielectric interface and a light point `x2` (or a light direction)
//! on the other, find the interface point `x1` where `x0 → x1 → x2` obeys Snell's law, by
//! Newton's method on the half-vector constraint, and the generalised geometry term of the
//! connection (the implicit-function-theorem derivative of `x1` with respect to the light
//! point). Everything is in `f64`: the constraint is a difference of nearly equal terms near
//! the solution.
//!
//! The solver sees the interface only through [`Interface::project`]: the point where the ray
//! from `x0` towards a target first crosses it, with the local geometry there (tangent plane,
//! interpolated shading normal and its derivatives). Steps are taken in the tangent plane and
//! projected back along the ray from `x0` (as in the paper), so a mesh is walked across
//! triangles by the ray casts, and every iterate is a point that `x0` sees.

use glam::DVec3;

/// The surface around a point of the interface, in world units (`f64`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InterfacePoint {
    /// Position.
    pub p: DVec3,
    /// Unit geometric normal, pointing to the side the light is on (the outside).
    pub ng: DVec3,
    /// Unit shading normal (interpolated vertex normals), in `ng`'s hemisphere.
    pub ns: DVec3,
    /// Two orthonormal tangents of the geometric tangent plane (the area measure at `p`).
    pub dpdu: [DVec3; 2],
    /// Derivative of the unit shading normal along each tangent of `dpdu` (1/length; zero on
    /// flat facets without vertex normals).
    pub dndu: [DVec3; 2],
}

/// The interface as the solver sees it.
pub trait Interface {
    /// The first crossing of the interface by the ray from `x0` through `target`, if the ray
    /// leaves through the interface there (no other surface in front, the right side).
    fn project(&mut self, x0: DVec3, target: DVec3) -> Option<InterfacePoint>;
}

/// Where the light is: a point on an area light with its unit normal, or a direction (a
/// distant light).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightTarget {
    /// A light point and its unit surface normal (the light emits to the side it points to).
    Point {
        /// Position.
        p: DVec3,
        /// Unit normal.
        n: DVec3,
    },
    /// A unit direction from the interface towards a distant light.
    Direction(DVec3),
}

impl LightTarget {
    /// A point along the straight line from `x0` to the light (for seeding with it).
    #[must_use]
    pub fn seed_target(&self, x0: DVec3) -> DVec3 {
        match *self {
            LightTarget::Point { p, .. } => p,
            LightTarget::Direction(d) => x0 + d,
        }
    }

    /// Unit direction from `x1` to the light and the distance (∞ for a direction).
    fn towards(&self, x1: DVec3) -> Option<(DVec3, f64)> {
        match *self {
            LightTarget::Point { p, .. } => {
                let v = p - x1;
                let l = v.length();
                (l > 0.0 && l.is_finite()).then(|| (v / l, l))
            }
            LightTarget::Direction(d) => Some((d, f64::INFINITY)),
        }
    }
}

/// Solver settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolverSettings {
    /// Converged when the constraint's norm (the sine of the angle between the generalised
    /// half vector and the shading normal) is below this.
    pub tolerance: f64,
    /// Newton iterations (including halved steps) before giving up.
    pub max_iterations: u32,
    /// Give up when the step length factor falls below this.
    pub min_step: f64,
}

impl Default for SolverSettings {
    fn default() -> Self {
        SolverSettings {
            tolerance: 1e-7,
            max_iterations: 40,
            min_step: 1e-4,
        }
    }
}

/// Why a connection has no solution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Failure {
    /// The straight line from `x0` to the light does not leave through the interface (another
    /// surface in front, or no crossing): no seed.
    Seed,
    /// Newton's method did not converge within the iteration budget, or stalled.
    NoConvergence,
    /// The walk ended where `x0` is beyond the critical angle: total internal reflection, no
    /// refracted path to the light exists near the seed.
    TotalInternalReflection,
    /// A converged point that is not a transmission from `x0` to the light (both on the same
    /// side of the interface), or a light point that faces away from `x1`.
    WrongSide,
    /// The constraint's derivative is singular (a caustic fold; the geometry term is infinite).
    Singular,
}

/// A refracted connection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Solution {
    /// The refraction point.
    pub x1: InterfacePoint,
    /// Unit direction from `x1` to `x0`.
    pub wa: DVec3,
    /// Distance `|x0 − x1|`.
    pub la: f64,
    /// Unit direction from `x1` to the light.
    pub wb: DVec3,
    /// Distance from `x1` to the light point (∞ for a direction).
    pub lb: f64,
    /// Generalised geometry term: `dω0/dA(x2)` (1/length²) for a light point, `dω0/dω_L`
    /// (unitless) for a direction (docs/references.md §5.3).
    pub geometry: f64,
    /// Newton iterations taken.
    pub iterations: u32,
}

/// An orthonormal pair perpendicular to unit `n` (Duff et al. 2017).
#[must_use]
pub fn tangents(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1.0f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        DVec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// The constraint at a point and its derivative along the point's tangents.
struct Constraint {
    c: [f64; 2],
    /// `j[i][k] = ∂C_i/∂u_k`.
    j: [[f64; 2]; 2],
    /// The shading frame's tangents (`C_i = ĥ · e_i`).
    e: [DVec3; 2],
    wa: DVec3,
    la: f64,
    wb: DVec3,
    lb: f64,
    /// Generalised half vector, unnormalised, and its length.
    h: DVec3,
    h_len: f64,
}

impl Constraint {
    fn norm(&self) -> f64 {
        (self.c[0] * self.c[0] + self.c[1] * self.c[1]).sqrt()
    }
}

/// Derivative of `ĥ = h/|h|` for a change `dh` of `h`.
fn d_unit(h: DVec3, h_len: f64, dh: DVec3) -> DVec3 {
    let hh = h / h_len;
    (dh - hh * hh.dot(dh)) / h_len
}

/// The half-vector constraint `C = (ĥ·s, ĥ·t)` with `h = η_a w_a + η_b w_b` (docs/references.md
/// §5.1) and its Jacobian with respect to the tangent coordinates of `x1`. The frame's own
/// rotation enters only through its normal part, `∂e_i·n = −e_i·∂n`; its in-plane part
/// multiplies the tangential part of `ĥ`, which vanishes at a solution, so the Jacobian is
/// exact there (where the geometry term is evaluated) and a close approximation elsewhere.
fn constraint(
    x0: DVec3,
    x1: &InterfacePoint,
    light: &LightTarget,
    eta_a: f64,
    eta_b: f64,
) -> Option<Constraint> {
    let va = x0 - x1.p;
    let la = va.length();
    if !(la > 0.0) {
        return None;
    }
    let wa = va / la;
    let (wb, lb) = light.towards(x1.p)?;
    let h = wa * eta_a + wb * eta_b;
    let h_len = h.length();
    if !(h_len > 1e-12) || !h_len.is_finite() {
        return None;
    }
    let hh = h / h_len;
    let (s, t) = tangents(x1.ns);
    let e = [s, t];
    // Column k: ∂C/∂u_k.
    let column = |dp: DVec3, dn: DVec3| -> [f64; 2] {
        let mut dh = -(dp - wa * wa.dot(dp)) * (eta_a / la);
        if lb.is_finite() {
            dh -= (dp - wb * wb.dot(dp)) * (eta_b / lb);
        }
        let dhh = d_unit(h, h_len, dh);
        let n_dot = hh.dot(x1.ns);
        e.map(|ei| dhh.dot(ei) - ei.dot(dn) * n_dot)
    };
    let c0 = column(x1.dpdu[0], x1.dndu[0]);
    let c1 = column(x1.dpdu[1], x1.dndu[1]);
    let j = [[c0[0], c1[0]], [c0[1], c1[1]]];
    Some(Constraint {
        c: [hh.dot(s), hh.dot(t)],
        j,
        e,
        wa,
        la,
        wb,
        lb,
        h,
        h_len,
    })
}

fn det2(m: &[[f64; 2]; 2]) -> f64 {
    m[0][0] * m[1][1] - m[0][1] * m[1][0]
}

/// `m⁻¹ v`, or `None` when `m` is (numerically) singular.
fn solve2(m: &[[f64; 2]; 2], v: [f64; 2]) -> Option<[f64; 2]> {
    let d = det2(m);
    let scale = m.iter().flatten().fold(0.0f64, |a, x| a.max(x.abs()));
    if !(d.abs() > 1e-14 * scale * scale) {
        return None;
    }
    Some([
        (m[1][1] * v[0] - m[0][1] * v[1]) / d,
        (m[0][0] * v[1] - m[1][0] * v[0]) / d,
    ])
}

/// Solves for the refraction point of `x0 → x1 → light` through `interface`, where `x0` is on
/// the side of IOR `eta_a` and the light on the side of IOR `eta_b`, seeded by the straight
/// line from `x0` to the light (docs/references.md §5.2). Each Newton step `Δu = J⁻¹ C` is
/// taken in the tangent plane, scaled by a factor β, and projected back along the ray from
/// `x0`; a step is accepted when the projection succeeds, the light stays above the tangent
/// plane (the half-vector constraint also has spurious zeros with both ends below it) and
/// `|C|` decreases (then β doubles up to 1); otherwise β halves from the same point.
pub fn solve<I: Interface>(
    interface: &mut I,
    x0: DVec3,
    light: &LightTarget,
    eta_a: f64,
    eta_b: f64,
    settings: &SolverSettings,
) -> Result<Solution, Failure> {
    solve_from(
        interface,
        x0,
        light.seed_target(x0),
        light,
        eta_a,
        eta_b,
        settings,
    )
}

/// [`solve`] from the seed where the ray from `x0` through `seed` crosses the interface
/// (used to look for other solutions than the straight line's).
pub fn solve_from<I: Interface>(
    interface: &mut I,
    x0: DVec3,
    seed: DVec3,
    light: &LightTarget,
    eta_a: f64,
    eta_b: f64,
    settings: &SolverSettings,
) -> Result<Solution, Failure> {
    let x1 = interface.project(x0, seed).ok_or(Failure::Seed)?;
    solve_from_point(interface, x0, x1, light, eta_a, eta_b, settings)
}

/// [`solve`] from a seed point already on the interface (as [`Interface::project`] returned it).
pub fn solve_from_point<I: Interface>(
    interface: &mut I,
    x0: DVec3,
    seed: InterfacePoint,
    light: &LightTarget,
    eta_a: f64,
    eta_b: f64,
    settings: &SolverSettings,
) -> Result<Solution, Failure> {
    let mut x1 = seed;
    let mut cur = constraint(x0, &x1, light, eta_a, eta_b).ok_or(Failure::Seed)?;
    let mut beta = 1.0f64;
    let mut iterations = 0;
    while cur.norm() >= settings.tolerance {
        if iterations >= settings.max_iterations || beta < settings.min_step {
            return Err(classify_failure(&cur, &x1, eta_a, eta_b));
        }
        iterations += 1;
        let Some(step) = solve2(&cur.j, cur.c) else {
            return Err(classify_failure(&cur, &x1, eta_a, eta_b));
        };
        let target = x1.p - (x1.dpdu[0] * step[0] + x1.dpdu[1] * step[1]) * beta;
        let next = interface
            .project(x0, target)
            .and_then(|p| constraint(x0, &p, light, eta_a, eta_b).map(|c| (p, c)));
        match next {
            Some((p, c)) if c.norm() < cur.norm() && c.wb.dot(p.ng) > 0.0 => {
                x1 = p;
                cur = c;
                beta = (2.0 * beta).min(1.0);
            }
            _ => beta *= 0.5,
        }
    }
    // A transmission: x0 below the tangent plane, the light above it (geometric and shading).
    let (wa, wb) = (cur.wa, cur.wb);
    if !(wa.dot(x1.ng) < 0.0 && wb.dot(x1.ng) > 0.0 && wa.dot(x1.ns) < 0.0 && wb.dot(x1.ns) > 0.0) {
        return Err(Failure::WrongSide);
    }
    if let LightTarget::Point { n, .. } = light {
        if !(n.dot(-wb) > 0.0) {
            return Err(Failure::WrongSide);
        }
    }
    let geometry = geometry_term(&cur, &x1, light, eta_b).ok_or(Failure::Singular)?;
    Ok(Solution {
        x1,
        wa,
        la: cur.la,
        wb,
        lb: cur.lb,
        geometry,
        iterations,
    })
}

/// Total internal reflection when the last iterate sees `x0` beyond the critical angle.
fn classify_failure(c: &Constraint, x1: &InterfacePoint, eta_a: f64, eta_b: f64) -> Failure {
    let cos_a = c.wa.dot(x1.ns).abs().min(1.0);
    let sin_a = (1.0 - cos_a * cos_a).sqrt();
    if eta_a > eta_b && eta_a * sin_a > eta_b {
        Failure::TotalInternalReflection
    } else {
        Failure::NoConvergence
    }
}

/// The generalised geometry term at a solution (docs/references.md §5.3): with `B = ∂C/∂v`
/// for the light point moving in its tangent plane (or the light direction on the unit
/// sphere), `∂u/∂v = −J⁻¹ B`, and `dω0/dv = |det B / det J| · |n_g·w_a| / |x0 − x1|²`.
fn geometry_term(
    c: &Constraint,
    x1: &InterfacePoint,
    light: &LightTarget,
    eta_b: f64,
) -> Option<f64> {
    let (q, scale) = match *light {
        LightTarget::Point { n, .. } => (tangents(n), eta_b / c.lb),
        LightTarget::Direction(d) => (tangents(d), eta_b),
    };
    // Column k: ∂C/∂v_k.
    let column = |qk: DVec3| -> [f64; 2] {
        let dh = match light {
            LightTarget::Point { .. } => (qk - c.wb * c.wb.dot(qk)) * scale,
            LightTarget::Direction(_) => qk * scale,
        };
        let dhh = d_unit(c.h, c.h_len, dh);
        c.e.map(|ei| dhh.dot(ei))
    };
    let (b0, b1) = (column(q.0), column(q.1));
    let b = [[b0[0], b1[0]], [b0[1], b1[1]]];
    let det_j = det2(&c.j);
    if !(det_j.abs() > 0.0) {
        return None;
    }
    let g = (det2(&b) / det_j).abs() * x1.ng.dot(c.wa).abs() / (c.la * c.la);
    g.is_finite().then_some(g)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An analytic sphere of radius `r` at the origin, crossed from inside.
    struct Ball {
        r: f64,
    }

    impl Interface for Ball {
        fn project(&mut self, x0: DVec3, target: DVec3) -> Option<InterfacePoint> {
            let d = (target - x0).try_normalize()?;
            let b = x0.dot(d);
            let disc = self.r * self.r - (x0 - d * b).length_squared();
            if disc < 0.0 {
                return None;
            }
            let n = (x0 + d * (-b + disc.sqrt())).normalize();
            let (s, t) = tangents(n);
            Some(InterfacePoint {
                p: n * self.r,
                ng: n,
                ns: n,
                dpdu: [s, t],
                dndu: [s / self.r, t / self.r],
            })
        }
    }

    /// dω0/dv by central differences: the light point moved in its tangent plane (or the
    /// light direction rotated), re-solved each time; the solid angle spanned by ω0.
    fn finite_difference<I: Interface>(
        i: &mut I,
        x0: DVec3,
        light: LightTarget,
        eta_a: f64,
        eta_b: f64,
    ) -> f64 {
        let settings = SolverSettings {
            tolerance: 1e-12,
            max_iterations: 100,
            ..SolverSettings::default()
        };
        let h = 1e-5;
        let (q1, q2) = match light {
            LightTarget::Point { n, .. } => tangents(n),
            LightTarget::Direction(d) => tangents(d),
        };
        let moved = |q: DVec3, e: f64| match light {
            LightTarget::Point { p, n } => LightTarget::Point { p: p + q * e, n },
            LightTarget::Direction(d) => LightTarget::Direction((d + q * e).normalize()),
        };
        let mut w = |l: LightTarget| -> DVec3 {
            let s = solve(i, x0, &l, eta_a, eta_b, &settings).expect("solvable");
            -s.wa
        };
        let d1 = (w(moved(q1, h)) - w(moved(q1, -h))) / (2.0 * h);
        let d2 = (w(moved(q2, h)) - w(moved(q2, -h))) / (2.0 * h);
        w(light).dot(d1.cross(d2)).abs()
    }

    #[test]
    fn sphere_geometry_term_matches_finite_differences() {
        let mut ball = Ball { r: 1.0 };
        let cases = [
            (DVec3::new(0.2, -0.3, 0.1), DVec3::new(-2.0, 2.5, 1.5)),
            (DVec3::new(-0.6, 0.1, 0.3), DVec3::new(3.0, 0.5, -1.0)),
            (DVec3::new(0.0, 0.0, 0.0), DVec3::new(0.0, 0.0, 4.0)),
        ];
        for (x0, lp) in cases {
            // A light point facing the ball, at an angle to the line of sight.
            let n = (-lp.normalize() + DVec3::new(0.2, 0.1, -0.1)).normalize();
            let light = LightTarget::Point { p: lp, n };
            let s = solve(&mut ball, x0, &light, 1.4, 1.0, &SolverSettings::default())
                .expect("solvable");
            // Snell's law at the solution.
            let cos_a = s.wa.dot(s.x1.ns).abs();
            let cos_b = s.wb.dot(s.x1.ns);
            let (sin_a, sin_b) = ((1.0 - cos_a * cos_a).sqrt(), (1.0 - cos_b * cos_b).sqrt());
            assert!((1.4 * sin_a - sin_b).abs() < 1e-6, "{x0}: {sin_a} {sin_b}");
            let fd = finite_difference(&mut ball, x0, light, 1.4, 1.0);
            assert!(
                (s.geometry - fd).abs() < 1e-5 * fd,
                "{x0}: G = {} vs finite differences {fd}",
                s.geometry
            );
            let dir = LightTarget::Direction((lp - x0).normalize());
            let s =
                solve(&mut ball, x0, &dir, 1.4, 1.0, &SolverSettings::default()).expect("solvable");
            let fd = finite_difference(&mut ball, x0, dir, 1.4, 1.0);
            assert!(
                (s.geometry - fd).abs() < 1e-5 * fd,
                "{x0} (direction): G = {} vs finite differences {fd}",
                s.geometry
            );
        }
    }

    /// Towards index matching (η_a → η_b; at equality the half vector vanishes and the
    /// constraint is undefined) the connection tends to the straight line and the geometry
    /// term to the ordinary one, cos θ_L / d².
    #[test]
    fn nearly_index_matched_geometry_term_is_the_inverse_square_law() {
        let mut ball = Ball { r: 1.0 };
        let x0 = DVec3::new(0.3, 0.2, -0.1);
        let p = DVec3::new(1.0, 2.0, 2.0);
        let n = DVec3::new(-0.3, -0.5, -0.8).normalize();
        let s = solve(
            &mut ball,
            x0,
            &LightTarget::Point { p, n },
            1.0001,
            1.0,
            &SolverSettings::default(),
        )
        .expect("solvable");
        let d = p - x0;
        let expected = n.dot(-d.normalize()) / d.length_squared();
        assert!(
            (s.geometry - expected).abs() < 1e-3 * expected,
            "{} vs {expected}",
            s.geometry
        );
    }

    #[test]
    fn beyond_the_critical_angle_is_total_internal_reflection() {
        // x0 near the surface, the light far off to the side in the tangent direction: only
        // grazing exits would reach it, and none exists within the critical cone.
        let mut ball = Ball { r: 1.0 };
        let x0 = DVec3::new(0.0, 0.0, 0.95);
        let light = LightTarget::Direction(DVec3::new(1.0, 0.0, -0.3).normalize());
        let r = solve(&mut ball, x0, &light, 1.5, 1.0, &SolverSettings::default());
        assert!(
            matches!(
                r,
                Err(Failure::TotalInternalReflection | Failure::NoConvergence | Failure::WrongSide)
            ),
            "{r:?}"
        );
    }
}
