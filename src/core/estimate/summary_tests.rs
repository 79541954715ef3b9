//! Tests of [`super`]: `summary.rs`.

use super::*;
use crate::core::numerics::rng::Rng;

/// [`most_probable_holding`] of `(probability, index)` items with
/// distinct indices.
fn holding(items: &[(f64, usize)], level: f64) -> (Vec<usize>, f64) {
    let len = items.iter().map(|x| x.1 + 1).max().unwrap_or(0);
    let mut probability = vec![0.0; len];
    for &(p, k) in items {
        probability[k] = p;
    }
    let indices: Vec<usize> = items.iter().map(|x| x.1).collect();
    most_probable_holding(&indices, &probability, 0.0, level)
}

#[test]
fn the_fewest_points_holding_a_level_match_sorting_them_all() {
    // Zero and NaN are never taken; a level above the total takes
    // every positive item; nothing positive, nothing taken.
    let items = vec![(0.25, 4), (0.0, 1), (f64::NAN, 2), (0.5, 3), (0.25, 0)];
    assert_eq!(holding(&items, 2.0), (vec![0, 3, 4], 1.0));
    assert_eq!(holding(&items, 0.6), (vec![0, 3], 0.75), "ties: the lower index first");
    assert_eq!(holding(&[(0.0, 0), (f64::NAN, 1)], 0.9), (Vec::new(), 0.0));
    assert_eq!(holding(&items, 0.0), (Vec::new(), 0.0));
    // The floor (here half the largest) leaves out what is at or
    // below it.
    let probability = [0.25, 0.0, f64::NAN, 0.5, 0.25];
    assert_eq!(
        most_probable_holding(&[0, 1, 2, 3, 4], &probability, 0.5, 2.0),
        (vec![3], 0.5)
    );
    assert_eq!(
        most_probable_holding(&[0, 1, 2, 3, 4], &probability, 0.49, 2.0),
        (vec![0, 3, 4], 1.0)
    );
    let mut rng = Rng::new(5);
    for n in [1, 7, 33, 200, 5000] {
        for sharp in [false, true] {
            let mut items: Vec<(f64, usize)> = (0..n)
                .map(|k| {
                    let p = rng.uniform();
                    (if sharp { p.powi(40) } else { p }, k)
                })
                .collect();
            // Ties: the lower index goes first.
            if n > 10 {
                items[3].0 = items[9].0;
            }
            let total: f64 = items.iter().map(|x| x.0).sum();
            for i in &mut items {
                i.0 /= total;
            }
            let mut sorted = items.clone();
            sorted.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
            let mut expected = Vec::new();
            let mut mass = 0.0;
            for (p, k) in &sorted {
                if mass >= 0.9 {
                    break;
                }
                expected.push(*k);
                mass += p;
            }
            let (got, got_mass) = holding(&items, 0.9);
            expected.sort_unstable();
            assert_eq!(got, expected, "n {n}, sharp {sharp}");
            assert!((got_mass - mass).abs() < 1e-12);
        }
    }
}

/// Each link's share is the sum of its points' probabilities and the
/// largest value shown on it, summed here point by point over the
/// whole surface (the summary reads the support in runs of one link).
#[test]
fn per_link_shares_add_up_their_points() {
    let robot = crate::core::robot::builtin::lwr4plus_generated().unwrap();
    let request = crate::core::surface::sampling::SurfaceRequest {
        links: robot.default_candidate_links(),
        total_points: 700,
        seed: 3,
    };
    let surface = Surface::sample(&robot, &request).unwrap();
    let pose = RobotPose::new(&robot, &robot.joint_positions(&[0.1; 7], &[]).unwrap());
    let n = surface.len();
    let mut rng = Rng::new(8);
    let mut probability: Vec<f64> = (0..n)
        .map(|_| {
            if rng.uniform() < 0.6 {
                rng.uniform().powi(3)
            } else {
                0.0
            }
        })
        .collect();
    let total: f64 = probability.iter().sum();
    for p in &mut probability {
        *p /= total;
    }
    let display: Vec<f64> = probability.iter().map(|p| p * rng.uniform_in(0.5, 2.0)).collect();
    let support: Vec<usize> = (0..n).filter(|&k| probability[k] > 0.0).collect();
    let posterior = Posterior {
        display: display.clone(),
        log_likelihood: probability.iter().map(|p| p.ln()).collect(),
        force_newtons: vec![5.0; n],
        phases: Vec::new(),
        phase_flags: vec![0; n],
        map_point: support[0],
        support,
        best_residual_chi2: 1.0,
        no_contact_chi2: 1e3,
        probability: probability.clone(),
    };
    let summary = summarize(&posterior, &surface, &pose, 7);
    let mut links = surface.link.clone();
    links.dedup();
    assert_eq!(summary.per_link.len(), links.len());
    for share in &summary.per_link {
        let on = (0..n).filter(|&k| surface.link[k] == share.link);
        let summed: f64 = on.clone().map(|k| probability[k]).sum();
        let max = on.map(|k| display[k]).fold(0.0, f64::max);
        assert!((share.summed - summed).abs() < 1e-12, "{share:?} vs {summed}");
        assert_eq!(share.max.to_bits(), max.to_bits(), "{share:?} vs {max}");
    }
    let all: f64 = summary.per_link.iter().map(|s| s.summed).sum();
    assert!((all - 1.0).abs() < 1e-12);
}

/// A contact's tangential force is its force less the part along its
/// normal: a 3-4-12 N force on a surface facing −z pushes 12 N along the
/// normal and drags 5 N along the surface.
#[test]
fn the_tangential_force_is_the_force_along_the_surface() {
    let contact = ContactEstimate {
        point: 0,
        link: 0,
        point_world: DVec3::ZERO,
        inward_normal_world: DVec3::Z,
        force_world: DVec3::new(3.0, 4.0, 12.0),
        force_newtons: 13.0,
        probability: 1.0,
    };
    let tangential = contact.tangential_world();
    assert!(tangential.distance(DVec3::new(3.0, 4.0, 0.0)) < 1e-12, "{tangential:?}");
    assert!((tangential.length() - 5.0).abs() < 1e-12);
}
