//! Image metadata that describes the scene as built: the estimators chosen per interior.

use std::collections::BTreeMap;

use crate::medium::Medium;
use crate::scene::Scene;

/// One `velour:interior.<object>` attribute per object with an interior: the interior's kind
/// and the estimators chosen for it (free flights, shadow-ray transmittance, majorants, NEE).
#[must_use]
pub fn estimator_attributes(scene: &Scene) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    for object in &scene.objects {
        let Some(medium) = object.medium.and_then(|m| scene.media.get(m as usize)) else {
            continue;
        };
        let what = match medium {
            Medium::Absorbing { .. } => "absorbing".to_string(),
            Medium::Homogeneous(_) => "homogeneous".to_string(),
            Medium::Heterogeneous(h) => format!(
                "heterogeneous; free_flight {:?}; transmittance {:?}; majorant {:?}",
                h.tracking.free_flight, h.tracking.transmittance, h.tracking.majorant
            ),
        };
        let name: String = object
            .name
            .chars()
            .map(|c| if c.is_ascii_graphic() { c } else { '_' })
            .collect();
        out.insert(
            format!("velour:interior.{name}"),
            format!("{what}; nee {:?}", object.nee),
        );
    }
    out
}
