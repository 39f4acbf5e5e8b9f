//! Grids that colour and light a medium per point: a per-vertex albedo (a colour grid, or a
//! scalar grid through a ramp, converted by the interior's albedo mode) and emission (a colour
//! grid, a scalar grid, or a temperature grid through blackbody radiance). Lookups are
//! trilinear in the grid's index space (docs/references.md §15.2–15.4).

use glam::Vec3;

use super::artist::{single_scattering_albedo_from_multiple, AlbedoMode};
use super::MAX_SINGLE_SCATTERING_ALBEDO;
use crate::grid::{Accessor, SparseGrid};
use crate::math::Ray;
use crate::spectrum::blackbody::BlackbodyTable;
use crate::spectrum::Rgb;

/// A per-vertex artist albedo read from a grid.
#[derive(Clone, Debug)]
pub struct AlbedoGrid {
    /// The grid, placed in the scene (same index-to-world map as the component's density).
    pub grid: SparseGrid,
    /// How the grid's values become a colour.
    pub source: AlbedoSource,
    /// How the artist albedo maps to the single-scattering albedo.
    pub mode: AlbedoMode,
    /// Mean cosine of the component's phase function (for the van de Hulst inversion).
    pub g: f32,
}

/// How an albedo grid's values become a colour.
#[derive(Clone, Debug, PartialEq)]
pub enum AlbedoSource {
    /// A Vec3 grid of colours.
    Colour,
    /// A scalar grid through a ramp of `(value, colour)` stops, sorted by value (linear
    /// between stops, clamped outside them).
    Ramp(Vec<(f32, Rgb)>),
}

impl AlbedoSource {
    /// The ramp's colour at `v` (linear between stops, the end colours outside).
    #[must_use]
    pub fn ramp(stops: &[(f32, Rgb)], v: f32) -> Rgb {
        let Some(&(v0, c0)) = stops.first() else {
            return Rgb::ZERO;
        };
        if !(v > v0) {
            return c0;
        }
        let mut prev = (v0, c0);
        for &(x, c) in stops.iter().skip(1) {
            if v <= x {
                let span = x - prev.0;
                let f = if span > 0.0 { (v - prev.0) / span } else { 1.0 };
                return prev.1 * (1.0 - f) + c * f;
            }
            prev = (x, c);
        }
        prev.1
    }
}

impl AlbedoGrid {
    /// The single-scattering albedo at world point `p`: the grid interpolated trilinearly at
    /// `p` (a colour, or a scalar through the ramp), clamped to [0, 1], then inverted as the
    /// interior's `albedo_mode` says (docs/references.md §15.4).
    #[must_use]
    pub fn single_scattering_at(&self, p: Vec3) -> Rgb {
        let ip = self.grid.world_to_index_point(p);
        let mut acc = Accessor::new(&self.grid, 0);
        let artist = match &self.source {
            AlbedoSource::Colour => {
                let v = acc.sample_trilinear_vec3(ip);
                Rgb::new(v.x, v.y, v.z)
            }
            AlbedoSource::Ramp(stops) => AlbedoSource::ramp(stops, acc.sample_trilinear(ip)),
        };
        let artist = artist.map(|a| if a.is_nan() { 0.0 } else { a.clamp(0.0, 1.0) });
        match self.mode {
            AlbedoMode::MultipleScattering => {
                artist.map(|a| single_scattering_albedo_from_multiple(a, self.g))
            }
            AlbedoMode::SingleScattering => artist.map(|a| a.min(MAX_SINGLE_SCATTERING_ALBEDO)),
        }
    }
}

/// Emitted radiance L_e read from a grid (docs/references.md §15.2–15.3).
#[derive(Clone, Debug)]
pub struct EmissionGrid {
    /// The grid, placed in the scene (same index-to-world map as the component's density).
    pub grid: SparseGrid,
    /// How the grid's values become radiance.
    pub kind: EmissionKind,
    /// Radiance multiplier per channel (`emission_scale` × `emission_color`).
    pub scale: Rgb,
}

/// How an emission grid's values become radiance.
#[derive(Clone, Debug)]
pub enum EmissionKind {
    /// A Vec3 grid of radiance.
    Colour,
    /// A scalar grid (times the colour in [`EmissionGrid::scale`]).
    Scalar,
    /// A scalar temperature grid (value × `scale` kelvin) through blackbody radiance.
    Temperature {
        /// Kelvin per grid unit (`temperature_scale`).
        scale: f32,
        /// Blackbody radiance over the grid's temperature range.
        table: BlackbodyTable,
    },
}

/// An index-space ray through a grid, for lookups by distance.
pub(super) struct GridRay<'a> {
    accessor: Accessor<'a>,
    o: Vec3,
    d: Vec3,
}

impl<'a> GridRay<'a> {
    pub(super) fn new(grid: &'a SparseGrid, ray: &Ray) -> Self {
        let w2i = grid.world_to_index();
        GridRay {
            accessor: Accessor::new(grid, 0),
            o: w2i.transform_point3(ray.o.as_dvec3()).as_vec3(),
            d: w2i.transform_vector3(ray.d.as_dvec3()).as_vec3(),
        }
    }
}

impl EmissionGrid {
    /// L_e at distance `t` of the ray `r` was prepared for.
    pub(super) fn at(&self, r: &mut GridRay<'_>, t: f32) -> Rgb {
        let p = r.o + r.d * t;
        let le = match &self.kind {
            EmissionKind::Colour => {
                let v = r.accessor.sample_trilinear_vec3(p);
                Rgb::new(v.x, v.y, v.z)
            }
            EmissionKind::Scalar => Rgb::splat(r.accessor.sample_trilinear(p)),
            EmissionKind::Temperature { scale, table } => {
                table.at(r.accessor.sample_trilinear(p) * scale)
            }
        };
        (le * self.scale).clamp_zero()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ramp_interpolates_between_sorted_stops() {
        let stops = [
            (0.0, Rgb::new(0.0, 0.0, 1.0)),
            (0.5, Rgb::new(1.0, 0.0, 0.0)),
            (1.0, Rgb::new(1.0, 1.0, 1.0)),
        ];
        assert_eq!(AlbedoSource::ramp(&stops, -1.0), Rgb::new(0.0, 0.0, 1.0));
        assert_eq!(AlbedoSource::ramp(&stops, 0.25), Rgb::new(0.5, 0.0, 0.5));
        assert_eq!(AlbedoSource::ramp(&stops, 0.75), Rgb::new(1.0, 0.5, 0.5));
        assert_eq!(AlbedoSource::ramp(&stops, 9.0), Rgb::ONE);
        assert_eq!(AlbedoSource::ramp(&[], 0.3), Rgb::ZERO);
    }
}
