//! Interiors read once per walk (docs/textures.md): an interior whose textured parameters
//! are read at the point where the path entered the object (`projection = "entry"`), the
//! medium then being homogeneous along that walk, and a `blend` of two interiors picked per
//! walk with the probability a mask gives at the entry point. The integrator resolves such
//! an interior into a [`WalkMedium`] when a path (or a shadow ray) enters the object, and
//! keeps it on its interior stack until it leaves; a path that re-enters resolves again.
//! A `voxel` or `fbm` interior with textured parameters ([`FieldInterior`]) keeps its density
//! field; only its coefficients per unit density are read at the entry point. A `mixture`
//! with textured components ([`TexturedMixture`]) keeps its components; their coefficients are
//! read at the entry point, whose texture coordinates ride on the stack
//! ([`WalkMedium::EntryPoint`]: four components' coefficients would not fit). A `fabric` with
//! textured yarn colours ([`FabricInterior`]) keeps its fibres; only its colours are read there.

use std::sync::Arc;

use super::artist::{AlbedoMode, Coefficients};
use super::mixture::TexturedMixture;
use super::{FabricInterior, HeterogeneousMedium, HomogeneousMedium, ScaledField};
use crate::math::Vec2;
use crate::phase::PhaseFunction;
use crate::spectrum::Rgb;
use crate::texture::{ColorParam, ScalarParam};

/// A homogeneous or absorbing interior with textured parameters, read at the entry point.
#[derive(Clone, Debug)]
pub struct EntryInterior {
    /// Artist albedo in [0, 1] (ignored when absorbing).
    pub albedo: ColorParam,
    /// Attenuation distance per channel (world units), > 0.
    pub attenuation: ColorParam,
    /// Density multiplier ≥ 0.
    pub density: ScalarParam,
    /// How the albedo is read.
    pub mode: AlbedoMode,
    /// Phase function.
    pub phase: PhaseFunction,
    /// True for an `absorption` interior (σ_a = density / attenuation, no scattering).
    pub absorbing: bool,
}

impl EntryInterior {
    /// The medium for a walk entering at texture coordinates `uv` with a footprint
    /// `width_uv` wide (texture units): the artist parameters read there and inverted as for
    /// a constant interior (notes eq. 1–3).
    #[must_use]
    pub fn at(&self, uv: Vec2, width_uv: f32) -> WalkMedium {
        let density = self.density.eval(uv, width_uv);
        let attenuation = self.attenuation.eval(uv, width_uv);
        if self.absorbing {
            return WalkMedium::Absorbing(attenuation.map(|d| {
                if d.is_infinite() {
                    0.0
                } else {
                    density / d
                }
            }));
        }
        let coefficients = Coefficients::from_artist(
            self.albedo.eval(uv, width_uv),
            attenuation,
            density,
            self.mode,
            self.phase.mean_cosine(),
        );
        WalkMedium::Homogeneous {
            coefficients,
            look: 0,
        }
    }
}

/// A `voxel` or `fbm` interior with textured `albedo`, `attenuation` or `density`, read at the
/// entry point: the density field is the scene's, the coefficients per unit density are the
/// walk's (constant along it), and the majorants scale with them, so tracking stays
/// conservative (docs/textures.md).
#[derive(Clone, Debug)]
pub struct FieldInterior {
    /// The field, its majorants, phase function, estimator choices and combined base medium
    /// (its own coefficients are those of the textures' means).
    pub medium: Arc<HeterogeneousMedium>,
    /// Artist albedo in [0, 1].
    pub albedo: ColorParam,
    /// Attenuation distance per channel at density 1 (world units), > 0.
    pub attenuation: ColorParam,
    /// Density multiplier ≥ 0.
    pub density: ScalarParam,
    /// How the albedo is read.
    pub mode: AlbedoMode,
}

impl FieldInterior {
    /// The coefficients per unit density of a walk entering at `uv` with a footprint
    /// `width_uv` wide, inverted as for constant parameters (notes eq. 1–3).
    #[must_use]
    pub fn at(&self, uv: Vec2, width_uv: f32, look: u8) -> WalkMedium {
        let c = Coefficients::from_artist(
            self.albedo.eval(uv, width_uv),
            self.attenuation.eval(uv, width_uv),
            self.density.eval(uv, width_uv),
            self.mode,
            self.medium.phase.mean_cosine(),
        );
        WalkMedium::Field {
            sigma_t: c.sigma_t(),
            sigma_s: c.sigma_s,
            look,
        }
    }
}

/// One look of a blend: an interior of the scene (any type, by index into the scene's
/// media) or one read at the entry point.
#[derive(Clone, Debug)]
pub enum WalkLook {
    /// A medium of the scene.
    Medium(u32),
    /// Textured parameters read at the entry point.
    Entry(EntryInterior),
    /// A density field with textured parameters read at the entry point.
    Field(FieldInterior),
    /// A mixture with textured components read at the entry point.
    Mixture(TexturedMixture),
    /// A fabric with textured yarn colours read at the entry point.
    Fabric(FabricInterior),
}

impl WalkLook {
    /// The medium of a walk entering at `uv`; `look` (0 for `a`, 1 for `b`) is recorded in
    /// it, to find the phase function again.
    #[must_use]
    pub fn at(&self, uv: Vec2, width_uv: f32, look: u8) -> WalkMedium {
        match self {
            WalkLook::Medium(i) => WalkMedium::Scene(*i),
            WalkLook::Field(f) => f.at(uv, width_uv, look),
            WalkLook::Mixture(_) => WalkMedium::EntryPoint { uv, width_uv, look },
            WalkLook::Fabric(f) => f.at(uv, width_uv, look),
            WalkLook::Entry(e) => match e.at(uv, width_uv) {
                WalkMedium::Homogeneous { coefficients, .. } => {
                    WalkMedium::Homogeneous { coefficients, look }
                }
                other => other,
            },
        }
    }
}

/// An interior resolved per walk.
#[derive(Clone, Debug)]
pub enum WalkInterior {
    /// `projection = "entry"`: textured parameters read at the entry point.
    Entry(EntryInterior),
    /// `projection = "entry"` on a `voxel` or `fbm` interior: coefficients read at the entry
    /// point, the density field kept.
    Field(FieldInterior),
    /// A `mixture` with textured components, or a `voxel`/`fbm` interior with a textured
    /// base medium (built as a mixture): the components' coefficients read at the entry
    /// point.
    Mixture(TexturedMixture),
    /// A `fabric` interior with textured yarn colours, read at the entry point.
    Fabric(FabricInterior),
    /// `type = "blend"`: look `a` with probability mask(uv) at the entry point, else `b`.
    Blend {
        /// The probability of `a`, in [0, 1].
        mask: ScalarParam,
        /// The first look.
        a: WalkLook,
        /// The second look.
        b: WalkLook,
    },
}

impl WalkInterior {
    /// True when resolving needs a random number (a blend's choice).
    #[must_use]
    pub fn is_random(&self) -> bool {
        matches!(self, WalkInterior::Blend { .. })
    }

    /// The medium of a walk entering at texture coordinates `uv` with a footprint
    /// `width_uv` wide; `u` in [0, 1) picks a blend's look (`a` when `u < mask(uv)`), so the
    /// expected image is mask · A + (1 − mask) · B.
    #[must_use]
    pub fn resolve(&self, uv: Vec2, width_uv: f32, u: f32) -> WalkMedium {
        match self {
            WalkInterior::Entry(e) => e.at(uv, width_uv),
            WalkInterior::Field(f) => f.at(uv, width_uv, 0),
            WalkInterior::Mixture(_) => WalkMedium::EntryPoint {
                uv,
                width_uv,
                look: 0,
            },
            WalkInterior::Fabric(f) => f.at(uv, width_uv, 0),
            WalkInterior::Blend { mask, a, b } => {
                if u < mask.eval(uv, width_uv) {
                    a.at(uv, width_uv, 0)
                } else {
                    b.at(uv, width_uv, 1)
                }
            }
        }
    }

    /// Look `look` (0: the interior itself or a blend's `a`, 1: `b`), borrowed.
    fn look_ref(&self, look: u8) -> LookRef<'_> {
        match self {
            WalkInterior::Entry(e) => LookRef::Entry(e),
            WalkInterior::Field(f) => LookRef::Field(f),
            WalkInterior::Mixture(m) => LookRef::Mixture(m),
            WalkInterior::Fabric(f) => LookRef::Fabric(f),
            WalkInterior::Blend { a, b, .. } => match if look == 0 { a } else { b } {
                WalkLook::Medium(_) => LookRef::Scene,
                WalkLook::Entry(e) => LookRef::Entry(e),
                WalkLook::Field(f) => LookRef::Field(f),
                WalkLook::Mixture(m) => LookRef::Mixture(m),
                WalkLook::Fabric(f) => LookRef::Fabric(f),
            },
        }
    }

    /// The phase function of look `look` (0: the entry interior or `a`, 1: `b`) when it is
    /// an entry-projected scattering interior.
    #[must_use]
    pub fn phase(&self, look: u8) -> Option<PhaseFunction> {
        match self.look_ref(look) {
            LookRef::Entry(e) => Some(e.phase),
            _ => None,
        }
    }

    /// The density field of look `look` (0: the interior itself or `a`, 1: `b`) when it is a
    /// textured `voxel` or `fbm` interior.
    #[must_use]
    pub fn field(&self, look: u8) -> Option<&Arc<HeterogeneousMedium>> {
        match self.look_ref(look) {
            LookRef::Field(f) => Some(&f.medium),
            _ => None,
        }
    }

    /// The textured mixture of look `look` (0: the interior itself or `a`, 1: `b`).
    #[must_use]
    pub fn mixture(&self, look: u8) -> Option<&TexturedMixture> {
        match self.look_ref(look) {
            LookRef::Mixture(m) => Some(m),
            _ => None,
        }
    }

    /// The textured fabric of look `look` (0: the interior itself or `a`, 1: `b`).
    #[must_use]
    pub fn fabric(&self, look: u8) -> Option<&FabricInterior> {
        match self.look_ref(look) {
            LookRef::Fabric(f) => Some(f),
            _ => None,
        }
    }

    /// The scene medium of a resolved walk medium: `Medium::Homogeneous` with the look's
    /// phase function, `Medium::Absorbing`, or `None` for a medium of the scene (by index).
    #[must_use]
    pub fn medium_of(&self, m: WalkMedium) -> Option<super::Medium> {
        match m {
            WalkMedium::Scene(_) => None,
            WalkMedium::Homogeneous { coefficients, look } => {
                Some(super::Medium::Homogeneous(HomogeneousMedium {
                    coefficients,
                    phase: self.phase(look)?,
                }))
            }
            WalkMedium::Absorbing(sigma_a) => Some(super::Medium::Absorbing { sigma_a }),
            WalkMedium::Field {
                sigma_t,
                sigma_s,
                look,
            } => Some(super::Medium::Scaled(ScaledField {
                medium: Arc::clone(self.field(look)?),
                sigma_t,
                sigma_s,
            })),
            // Texture reads at every use: the price of not storing the coefficients.
            WalkMedium::EntryPoint { uv, width_uv, look } => Some(super::Medium::ScaledMixture(
                self.mixture(look)?.at(uv, width_uv),
            )),
            WalkMedium::Fabric { uv, width_uv, look } => Some(super::Medium::Dyed(
                self.fabric(look)?.medium_at(uv, width_uv),
            )),
        }
    }
}

/// One look of a [`WalkInterior`], borrowed: what [`WalkInterior::phase`],
/// [`WalkInterior::field`], [`WalkInterior::mixture`] and [`WalkInterior::fabric`] pick from.
enum LookRef<'a> {
    /// A medium of the scene (nothing resolved per walk).
    Scene,
    Entry(&'a EntryInterior),
    Field(&'a FieldInterior),
    Mixture(&'a TexturedMixture),
    Fabric(&'a FabricInterior),
}

/// The medium one walk uses inside an object with a [`WalkInterior`]: small and `Copy`, so
/// that it rides on the path's interior stack (and on the copies shadow rays take); the
/// phase function stays with the [`WalkInterior`] ([`WalkInterior::medium_of`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum WalkMedium {
    /// A medium of the scene, by index.
    Scene(u32),
    /// A homogeneous scattering medium with these coefficients; `look` is 0 for an entry
    /// interior or a blend's `a`, 1 for `b`.
    Homogeneous {
        /// σ_a and σ_s.
        coefficients: Coefficients,
        /// Which look.
        look: u8,
    },
    /// An absorbing medium with this σ_a (1/length).
    Absorbing(Rgb),
    /// A textured `voxel` or `fbm` look's density field with these coefficients per unit
    /// density; `look` as for `Homogeneous`.
    Field {
        /// Extinction per unit density (1/length).
        sigma_t: Rgb,
        /// Scattering per unit density (1/length).
        sigma_s: Rgb,
        /// Which look.
        look: u8,
    },
    /// A textured mixture's entry point: its components' coefficients are read there again
    /// whenever the walk's medium is needed; `look` as for `Homogeneous`.
    EntryPoint {
        /// Texture coordinates of the entry point.
        uv: Vec2,
        /// Footprint there (texture units).
        width_uv: f32,
        /// Which look.
        look: u8,
    },
    /// A textured fabric look entered at texture coordinates `uv` with a footprint
    /// `width_uv` wide, where its yarn colours are read; `look` as for `Homogeneous`.
    Fabric {
        /// The entry point's texture coordinates.
        uv: Vec2,
        /// The entry point's footprint (texture units).
        width_uv: f32,
        /// Which look.
        look: u8,
    },
}
