//! A fibre phase function prepared once per scattering vertex (`FibrePhase::prepare`, the
//! integrator's next event estimation and sampling at one vertex) gives bit-identical values,
//! pdfs and samples to the unprepared calls, for every direction it is reused for, with the
//! per-offset terms cached (automatic node counts) and partly recomputed (256 nodes).

use velour::fabric::{FibrePhase, FibrePhaseParams};
use velour::sampling::{sample_uniform_sphere, Rng};
use velour::spectrum::Rgb;

#[test]
fn prepared_vertex_matches_unprepared_bit_for_bit() {
    let mut rng = Rng::new(11, 0);
    for params in [
        FibrePhaseParams::default(),
        FibrePhaseParams {
            alpha: 0.04,
            beta_m: 0.15,
            beta_n: 0.5,
            ..Default::default()
        }
        .with_colour(Rgb::new(0.72, 0.1, 0.09)),
        FibrePhaseParams {
            h_nodes: 256,
            ..Default::default()
        }
        .with_colour(Rgb::new(0.86, 0.82, 0.72)),
    ] {
        let ph = FibrePhase::new(params).unwrap();
        for _ in 0..200 {
            let t = sample_uniform_sphere(rng.next_2d());
            let wo = sample_uniform_sphere(rng.next_2d());
            let prepared = ph.prepare(wo, t);
            for _ in 0..8 {
                let wi = sample_uniform_sphere(rng.next_2d());
                let (v, p) = ph.eval_pdf_prepared(&prepared, wi);
                assert_eq!(v, ph.eval(wo, wi, t));
                assert_eq!(p.to_bits(), ph.pdf(wo, wi, t).to_bits());
                let u = [
                    rng.next_f32(),
                    rng.next_f32(),
                    rng.next_f32(),
                    rng.next_f32(),
                ];
                assert_eq!(ph.sample_prepared(&prepared, u), ph.sample(wo, t, u));
            }
        }
    }
}
