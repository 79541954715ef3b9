//! The temporal model, its filter, smoother and offsets against brute force.

use super::*;
use crate::core::estimate::contact::PatchForms;
use crate::core::over_time::graph::*;
use crate::core::over_time::offsets::*;
use crate::core::over_time::smoother::*;

/// The branch-free loop of `PatchInformation::from_forms`, in the copy
/// for the widest vector unit, against the plain formulas (with
/// `f64::clamp`) sample by sample, bit for bit but for the shared
/// Occam charge; samples whose torques do not see the push (a ≤ 0,
/// NaN, ∞) get no contact's fit.
/// The filter's gains, four samples at a time without branches,
/// against [`Offset::absorb_within`] one sample at a time: random
/// offsets and frames (means within and beyond the patch's reach),
/// samples the frame did not score (-∞, NaN) and precisions that are
/// not positive definite keep their likelihood and offset.
#[test]
fn gains_in_lanes_match_absorbing_one_sample_at_a_time() {
    use crate::core::numerics::rng::Rng;
    let n = 1003;
    let mut rng = Rng::new(17);
    let mut offsets = Vec::new();
    let mut patch = Vec::new();
    let mut points = Vec::new();
    let mut window_m = Vec::new();
    for _ in 0..n {
        let rho = rng.uniform_in(0.002, 0.02);
        let q = 1.0 / (rho * rho);
        let (s11, s22) = (q * rng.uniform_in(0.5, 3.0), q * rng.uniform_in(0.5, 3.0));
        let s12 = rng.uniform_in(-0.9, 0.9) * (s11 * s22).sqrt();
        // Shifts from means of about a window.
        let (x1, x2) = (rng.uniform_in(-1.0, 1.0) * rho, rng.uniform_in(-1.0, 1.0) * rho);
        offsets.push(Offset {
            precision: [s11, s12, s22],
            shift: [s11 * x1 + s12 * x2, s12 * x1 + s22 * x2],
        });
        let (m11, m22) = (q * rng.uniform_in(0.0, 50.0), q * rng.uniform_in(0.0, 50.0));
        let m12 = rng.uniform_in(-0.99, 0.99) * (m11 * m22).sqrt();
        let (y1, y2) = (rng.uniform_in(-2.0, 2.0) * rho, rng.uniform_in(-2.0, 2.0) * rho);
        patch.push(PatchInformation {
            point: rng.uniform_in(-200.0, 0.0),
            information: [m11, m12, m22],
            shift: [m11 * y1 + m12 * y2, m12 * y1 + m22 * y2],
        });
        points.push(rng.uniform_in(-200.0, 0.0));
        window_m.push(rho);
    }
    points[3] = f64::NEG_INFINITY;
    patch[4].point = f64::NAN;
    offsets[5].precision = [1.0, 2.0, 1.0];
    patch[6].information = [f64::INFINITY, 0.0, 1.0];
    let (gains, after) = widest(GainsKernel {
        points: &points,
        patch: &patch,
        offsets: &offsets,
        window_m: &window_m,
    });
    assert_eq!((gains.len(), after.len()), (n, n));
    let mut beyond = 0;
    for k in 0..n {
        let (l, frame, offset) = (points[k], patch[k], offsets[k]);
        let (want_gain, want_after) = if !l.is_finite() || !frame.point.is_finite() {
            (l, offset)
        } else {
            let (gain, absorbed) = offset.absorb_within(&frame, PATCH_REACH * window_m[k]);
            let (free, _) = offset.absorb_within(&frame, f64::INFINITY);
            if (free - gain).abs() > 1e-9 {
                beyond += 1;
            }
            (frame.point + gain, absorbed)
        };
        let close =
            |x: f64, y: f64| x.to_bits() == y.to_bits() || (x - y).abs() <= 1e-12 * x.abs().max(y.abs()).max(1.0);
        assert!(
            close(gains[k], want_gain) || (gains[k].is_nan() && want_gain.is_nan()),
            "sample {k}: {} vs {want_gain}",
            gains[k]
        );
        assert_eq!(after[k], want_after, "sample {k}");
    }
    assert!(
        beyond > 50 && beyond < n - 50,
        "{beyond} samples charged beyond the reach"
    );
}

#[test]
fn patch_information_matches_the_plain_formulas_bit_for_bit() {
    let n = 503;
    let mut forms = PatchForms::random(9, n, -10.0, 1e4);
    forms.a[7] = f64::NAN;
    forms.a[8] = 0.0;
    forms.a[9] = f64::INFINITY;
    let (c, range) = (300.0, (1.0, 30.0));
    let got = PatchInformation::from_forms(&forms, c, range);
    let occam = got
        .iter()
        .zip(&forms.a)
        .find(|(_, a)| !(**a > 0.0 && a.is_finite()))
        .map(|(p, _)| p.point + 0.5 * c)
        .unwrap();
    // The Occam charge is read back from an unseen sample (to rounding).
    let bits = |p: &PatchInformation| {
        [
            p.information[0],
            p.information[1],
            p.information[2],
            p.shift[0],
            p.shift[1],
        ]
        .map(f64::to_bits)
    };
    for (k, found) in got.iter().enumerate() {
        let (a, b) = (forms.a[k], forms.b[k]);
        let want = if a > 0.0 && a.is_finite() {
            let inv_a = 1.0 / a;
            let f0 = (b * inv_a).clamp(range.0, range.1);
            let chi2 = (c - 2.0 * b * f0 + a * f0 * f0).max(0.0);
            let (h1, h2) = (forms.h1[k], forms.h2[k]);
            let m11 = (forms.g11[k] - h1 * h1 * inv_a).max(0.0);
            let m22 = (forms.g22[k] - h2 * h2 * inv_a).max(0.0);
            let limit = (m11 * m22).sqrt();
            let m12 = (forms.g12[k] - h1 * h2 * inv_a).clamp(-limit, limit);
            let f2 = f0 * f0;
            PatchInformation {
                point: -0.5 * chi2 + occam,
                information: [f2 * m11, f2 * m12, f2 * m22],
                shift: [f0 * (forms.e1[k] - h1 * b * inv_a), f0 * (forms.e2[k] - h2 * b * inv_a)],
            }
        } else {
            PatchInformation {
                point: -0.5 * c + occam,
                ..PatchInformation::default()
            }
        };
        assert_eq!(bits(found), bits(&want), "sample {k}");
        assert!(
            (found.point - want.point).abs() <= 1e-9 * want.point.abs().max(1.0),
            "sample {k}: {} against {}",
            found.point,
            want.point
        );
    }
}

/// A chain of `n` samples 1 cm apart, each hop weight `(1/m_k + 1/m_j)/d²`.
fn chain(n: usize) -> SurfaceGraph {
    let d2 = 1e-4;
    let count = |k: usize| if k == 0 || k + 1 == n { 1.0 } else { 2.0 };
    let mut g = SurfaceGraph::default();
    for k in 0..n {
        g.start.push(g.neighbour.len() as u32);
        let mut rate = 0.0;
        for j in [k.wrapping_sub(1), k + 1] {
            if j < n {
                let w = (1.0 / count(k) + 1.0 / count(j)) / d2;
                g.neighbour.push(j as u32);
                g.weight.push(w);
                rate += w;
            }
        }
        g.max_rate = g.max_rate.max(rate);
    }
    g.start.push(g.neighbour.len() as u32);
    g
}

fn model(n: usize, settings: TemporalSettings) -> TemporalModel {
    let graph = chain(n);
    TemporalModel {
        settings,
        hop_rate: (0..n).map(|k| graph.neighbours(k).1.iter().sum()).collect(),
        window_m: Vec::new(),
        graph,
        prior: (0..n)
            .map(|k| (k + 1) as f64)
            .map(|w| w / (n * (n + 1) / 2) as f64)
            .collect(),
        ln_prior: (0..n)
            .map(|k| ((k + 1) as f64 / (n * (n + 1) / 2) as f64).ln())
            .collect(),
        store_limit_bytes: DEFAULT_STORE_BYTES,
    }
}

/// The transition matrix over states (no contact first) written out
/// densely from the model's definition: the walk as repeated dense
/// Euler steps.
fn dense_transitions(m: &TemporalModel, dt: f64) -> Vec<Vec<f64>> {
    let n = m.prior.len();
    let s = m.settings;
    let p = |rate: f64| 1.0 - (-rate * dt).exp();
    let (on, off, jump) = (p(s.onset_per_s), p(s.release_per_s), p(s.jump_per_s));
    let scale = s.slide_m_per_sqrt_s * s.slide_m_per_sqrt_s;
    let fastest = m.graph.max_rate * scale;
    let steps = ((fastest * dt / 0.5).ceil() as usize).max(1);
    let h = (dt / steps as f64).min(0.5 / fastest) * scale;
    let mut walk: Vec<Vec<f64>> = (0..n)
        .map(|i| (0..n).map(|j| f64::from(u8::from(i == j))).collect())
        .collect();
    for _ in 0..steps {
        let mut next = walk.clone();
        for i in 0..n {
            for j in 0..n {
                let (around, weights) = m.graph.neighbours(j);
                let flow: f64 = around
                    .iter()
                    .zip(weights)
                    .map(|(&l, &w)| w * (walk[i][l as usize] - walk[i][j]))
                    .sum();
                next[i][j] = walk[i][j] + h * flow;
            }
        }
        walk = next;
    }
    let mut t = vec![vec![0.0; n + 1]; n + 1];
    t[0][0] = 1.0 - on;
    for j in 0..n {
        t[0][j + 1] = on * m.prior[j];
        t[j + 1][0] = off;
        for k in 0..n {
            t[j + 1][k + 1] = (1.0 - off) * ((1.0 - jump) * walk[j][k] + jump * m.prior[k]);
        }
    }
    t
}

/// Smoothing by summing over every path of states (independent of the
/// message passing): P(state at t | all frames).
fn brute_force(m: &TemporalModel, times: &[f64], frames: &[FrameLikelihood]) -> Vec<Vec<f64>> {
    let n = m.prior.len() + 1;
    let init = m.initial();
    let start: Vec<f64> = std::iter::once(init.no_contact)
        .chain(init.points.iter().copied())
        .collect();
    let lik = |t: usize, s: usize| -> f64 {
        if s == 0 {
            frames[t].no_contact.exp()
        } else {
            frames[t].points[s - 1].exp()
        }
    };
    let steps: Vec<Vec<Vec<f64>>> = (1..times.len())
        .map(|t| dense_transitions(m, times[t] - times[t - 1]))
        .collect();
    let len = times.len();
    let mut marginal = vec![vec![0.0; n]; len];
    let mut path = vec![0usize; len];
    loop {
        let mut w = start[path[0]] * lik(0, path[0]);
        for t in 1..len {
            w *= steps[t - 1][path[t - 1]][path[t]] * lik(t, path[t]);
        }
        for t in 0..len {
            marginal[t][path[t]] += w;
        }
        // Next path (odometer).
        let mut i = 0;
        loop {
            if i == len {
                for row in &mut marginal {
                    let total: f64 = row.iter().sum();
                    for v in row.iter_mut() {
                        *v /= total;
                    }
                }
                return marginal;
            }
            path[i] += 1;
            if path[i] < n {
                break;
            }
            path[i] = 0;
            i += 1;
        }
    }
}

fn frames() -> (Vec<f64>, Vec<FrameLikelihood>) {
    let times = vec![0.0, 0.005, 0.012, 0.5, 0.505];
    let frames = vec![
        FrameLikelihood {
            no_contact: -1.0,
            points: vec![-3.0, -0.5, -2.0, -4.0],
            patch: Vec::new(),
        },
        FrameLikelihood {
            no_contact: -6.0,
            points: vec![-1.0, -0.2, -5.0, -9.0],
            patch: Vec::new(),
        },
        FrameLikelihood {
            no_contact: -2.0,
            points: vec![-2.5, -1.5, -0.3, f64::NEG_INFINITY],
            patch: Vec::new(),
        },
        FrameLikelihood {
            no_contact: -0.1,
            points: vec![-3.0, -3.0, -1.0, -2.0],
            patch: Vec::new(),
        },
        FrameLikelihood {
            no_contact: -4.0,
            points: vec![-0.4, -2.0, -2.0, -0.1],
            patch: Vec::new(),
        },
    ];
    (times, frames)
}

#[test]
fn the_smoother_matches_summing_over_every_path() {
    let settings = TemporalSettings {
        onset_per_s: 3.0,
        release_per_s: 5.0,
        slide_m_per_sqrt_s: 0.03,
        jump_per_s: 2.0,
        step_secs: 0.0,
    };
    let m = model(4, settings);
    let (times, frames) = frames();
    let exact = brute_force(&m, &times, &frames);
    let mut smoother = Smoother::new(&m);
    for (t, f) in times.iter().zip(&frames) {
        smoother.push(*t, f).unwrap();
    }
    let smoothed = smoother.finish().unwrap();
    for (t, (b, e)) in smoothed.iter().zip(&exact).enumerate() {
        let got: Vec<f64> = std::iter::once(b.no_contact).chain(b.points.iter().copied()).collect();
        for (g, x) in got.iter().zip(e) {
            assert!((g - x).abs() < 1e-6, "frame {t}: {got:?} vs {e:?}");
        }
    }
    // The filter's last belief is the smoother's last.
    let mut filter = Filter::new(&m);
    let mut last = None;
    for (t, f) in times.iter().zip(&frames) {
        last = Some(filter.step(*t, f).unwrap().clone());
    }
    let last = last.unwrap();
    let end = exact.last().unwrap();
    assert!((last.no_contact - end[0]).abs() < 1e-6);
}

#[test]
fn the_walk_keeps_the_total_and_spreads_as_the_length_scale_says() {
    let n = 201;
    let g = chain(n);
    let mut v = vec![0.0; n];
    v[100] = 1.0;
    let mut scratch = Vec::new();
    let (l, t) = (0.02, 0.5);
    g.diffuse(&mut v, l * l, t, &mut scratch);
    let total: f64 = v.iter().sum();
    assert!((total - 1.0).abs() < 1e-12, "{total}");
    assert!(v.iter().all(|&x| x >= 0.0));
    // On a line of spacing d with weights 1/d² per neighbour the
    // variance grows by 2ℓ² per second (a chain is one surface
    // direction with twice the per-direction rate).
    let var: f64 = v
        .iter()
        .enumerate()
        .map(|(k, p)| p * ((k as f64 - 100.0) * 0.01).powi(2))
        .sum();
    assert!((var / (2.0 * l * l * t) - 1.0).abs() < 0.05, "variance {var}");
}

#[test]
fn a_persistent_contact_is_believed_and_its_end_is_noticed() {
    let m = model(4, TemporalSettings::default());
    let mut filter = Filter::new(&m);
    let favour = |k: usize, strength: f64| FrameLikelihood {
        no_contact: -strength,
        points: (0..4).map(|j| if j == k { 0.0 } else { -strength }).collect(),
        patch: Vec::new(),
    };
    for i in 0..40 {
        let b = filter.step(f64::from(i) * 0.005, &favour(2, 3.0)).unwrap();
        if i >= 3 {
            assert!(b.contact_probability() > 0.9, "frame {i}: {}", b.contact_probability());
            assert!(b.points[2] > 0.8);
        }
    }
    let quiet = FrameLikelihood {
        no_contact: 0.0,
        points: vec![-3.0; 4],
        patch: Vec::new(),
    };
    let mut p = 1.0;
    for i in 40..50 {
        p = filter.step(f64::from(i) * 0.005, &quiet).unwrap().contact_probability();
    }
    assert!(p < 0.1, "{p}");
}

#[test]
fn bad_settings_frames_and_times_are_errors() {
    let bad = TemporalSettings {
        slide_m_per_sqrt_s: f64::NAN,
        ..TemporalSettings::default()
    };
    assert!(matches!(
        bad.validate(),
        Err(TemporalError::BadSetting { name: "slide", .. })
    ));
    let m = model(3, TemporalSettings::default());
    let mut filter = Filter::new(&m);
    let short = FrameLikelihood {
        no_contact: 0.0,
        points: vec![0.0; 2],
        patch: Vec::new(),
    };
    assert!(matches!(
        filter.step(0.0, &short),
        Err(TemporalError::WrongLength { .. })
    ));
    let ok = FrameLikelihood {
        no_contact: 0.0,
        points: vec![0.0; 3],
        patch: Vec::new(),
    };
    filter.step(1.0, &ok).unwrap();
    assert!(matches!(filter.step(0.5, &ok), Err(TemporalError::BadTime { .. })));
    assert!(matches!(filter.step(f64::NAN, &ok), Err(TemporalError::BadTime { .. })));
    // Every likelihood -inf but no contact's: no contact, no NaN.
    let none = FrameLikelihood {
        no_contact: -1e9,
        points: vec![f64::NEG_INFINITY; 3],
        patch: Vec::new(),
    };
    let b = filter.step(2.0, &none).unwrap();
    assert!(b.no_contact.is_finite() && (b.no_contact - 1.0).abs() < 1e-12);
}

type Integrand<'a> = &'a dyn Fn(f64, f64) -> f64;

/// `∫ f(s) ds` over a square of half-width `half` (m) about 0.
fn integrate_2d(half: f64, f: impl Fn(f64, f64) -> f64) -> f64 {
    let steps = 600;
    let h = 2.0 * half / f64::from(steps);
    let mut total = 0.0;
    for i in 0..steps {
        for j in 0..steps {
            let x = -half + (f64::from(i) + 0.5) * h;
            let y = -half + (f64::from(j) + 0.5) * h;
            total += f(x, y);
        }
    }
    total * h * h
}

fn density(o: &Offset, x: f64, y: f64) -> f64 {
    let [l11, l12, l22] = o.precision;
    let [m1, m2] = o.mean_m();
    let (dx, dy) = (x - m1, y - m2);
    (o.det().sqrt() / std::f64::consts::TAU) * (-0.5 * (l11 * dx * dx + 2.0 * l12 * dx * dy + l22 * dy * dy)).exp()
}

/// Offsets against brute-force integration over the plane: a frame
/// absorbed, a forward and a backward belief combined, a mixture with
/// the window matched by its moments.
#[test]
fn offsets_integrate_as_brute_force_does() {
    let rho = 0.004;
    let prior = Offset {
        precision: [9e4, 2e4, 5e4],
        shift: [120.0, -40.0],
    };
    let frame = PatchInformation {
        point: 0.0,
        information: [3e5, -1e5, 8e4],
        shift: [900.0, 150.0],
    };
    let (gain, after) = prior.absorb_within(&frame, f64::INFINITY);
    let brute = integrate_2d(0.03, |x, y| {
        let [m11, m12, m22] = frame.information;
        let l = frame.shift[0] * x + frame.shift[1] * y - 0.5 * (m11 * x * x + 2.0 * m12 * x * y + m22 * y * y);
        density(&prior, x, y) * l.exp()
    });
    assert!((gain - brute.ln()).abs() < 1e-4, "{gain} vs {}", brute.ln());
    let backward = Offset {
        precision: [2e5, -3e4, 1.5e5],
        shift: [-300.0, 500.0],
    };
    let window = Offset::window(rho);
    let brute = integrate_2d(0.03, |x, y| {
        density(&after, x, y) * density(&backward, x, y) / density(&window, x, y)
    });
    let got = overlap(&after, &backward, rho);
    assert!((got - brute.ln()).abs() < 1e-4, "{got} vs {}", brute.ln());
    let own = 0.7;
    let mixed = after.mixed_with_window(own, rho);
    let moments = |f: &dyn Fn(f64, f64) -> f64| {
        let of = |o: &Offset| integrate_2d(0.03, |x, y| density(o, x, y) * f(x, y));
        (of(&mixed), own * of(&after) + (1.0 - own) * of(&window))
    };
    let tests: [(&str, Integrand, f64); 5] = [
        ("x", &|x, _| x, 1e-6),
        ("y", &|_, y| y, 1e-6),
        ("xx", &|x, _| x * x, 1e-8),
        ("xy", &|x, y| x * y, 1e-8),
        ("yy", &|_, y| y * y, 1e-8),
    ];
    for (name, f, tol) in tests {
        let (got, want) = moments(f);
        assert!((got - want).abs() < tol, "{name}: {got} vs {want}");
    }
}

/// A mean beyond the patch's reach is brought back to it, at a cost.
#[test]
fn offsets_stay_within_the_patch() {
    let rho = 0.005;
    let far = Offset {
        precision: [1e6, 0.0, 1e6],
        shift: [1e6 * 0.03, 0.0],
    };
    let (penalty, kept) = far.confined(rho);
    let [m1, m2] = kept.mean_m();
    assert!((m1 - PATCH_REACH * rho).abs() < 1e-12 && m2.abs() < 1e-12, "{m1} {m2}");
    let d = 0.03 - PATCH_REACH * rho;
    assert!((penalty - 0.5 * 1e6 * d * d).abs() < 1e-9, "{penalty}");
    let near = Offset::window(rho);
    assert_eq!(near.confined(rho), (0.0, near));
    // Absorbing a frame that pulls the mean out of reach charges the
    // change of the confinement's cost, and keeps the Gaussian whole.
    let pull = PatchInformation {
        point: 0.0,
        information: [4e5, 0.0, 4e5],
        shift: [4e5 * 0.02, 0.0],
    };
    let start = Offset::window(rho);
    let (free, whole) = start.absorb_within(&pull, f64::INFINITY);
    let (kept, same) = start.absorb_within(&pull, PATCH_REACH * rho);
    assert_eq!(whole, same);
    let expected = free - (whole.confined(rho).0 - start.confined(rho).0);
    assert!(whole.confined(rho).0 > 1.0);
    assert!((kept - expected).abs() < 1e-9, "{kept} vs {expected}");
}

/// The magnitude is profiled per frame with one Occam charge for all
/// samples: two samples that explain the torques equally well score
/// the same whatever their lever arms (a per-sample charge would
/// favour the weaker lever by `ln 2` per frame here, a hundred-frame
/// press by 69 nats).
#[test]
fn equally_good_fits_score_the_same_whatever_the_lever() {
    // τ = (2, 0) with σ = 1: sample 0 has u = (1, 0), sample 1 u = (0.5, 0).
    let forms = PatchForms {
        a: vec![1.0, 0.25],
        b: vec![2.0, 1.0],
        h1: vec![0.0; 2],
        h2: vec![0.0; 2],
        e1: vec![0.0; 2],
        e2: vec![0.0; 2],
        g11: vec![1.0; 2],
        g12: vec![0.0; 2],
        g22: vec![1.0; 2],
        window_m: vec![0.01; 2],
        ln_area: vec![0.0; 2],
    };
    let info = PatchInformation::from_forms(&forms, 4.0, (0.5, 10.0));
    assert!((info[0].point - info[1].point).abs() < 1e-12, "{info:?}");
    // Both fit exactly (f = 2 and 4): χ² = 0, so only the charge is
    // left, at the upper median `a` (1).
    let charge = 0.5 * std::f64::consts::TAU.ln() - 9.5_f64.ln();
    assert!((info[0].point - charge).abs() < 1e-12, "{info:?}");
}

#[test]
fn recordings_are_told_from_sets_of_unrelated_frames() {
    let d = TemporalSettings::default();
    let at = |dt: f64| (0..10).map(|i| f64::from(i) * dt).collect::<Vec<_>>();
    assert!(is_continuous_recording(&at(0.005), &d));
    assert!(is_continuous_recording(&at(0.3), &d));
    assert!(!is_continuous_recording(&at(0.4), &d));
    assert!(!is_continuous_recording(&at(1.0), &d));
    assert!(!is_continuous_recording(&[0.0], &d));
}

/// A recording of `n` frames at 1 kHz over the four-sample chain: free,
/// then presses on samples 1 and 2 (the one on 2 long), with noise.
fn long_recording(n: usize, seed: u64) -> (Vec<f64>, Vec<FrameLikelihood>) {
    use crate::core::numerics::rng::Rng;
    let mut rng = Rng::new(seed);
    let mut times = Vec::with_capacity(n);
    let mut frames = Vec::with_capacity(n);
    for i in 0..n {
        times.push(i as f64 * 1e-3);
        let pressed = match i % 1500 {
            200..=500 => Some(1),
            800..=1400 => Some(2),
            _ => None,
        };
        let mut points: Vec<f64> = (0..4).map(|_| rng.uniform_in(-12.0, -6.0)).collect();
        if let Some(k) = pressed {
            points[k] = rng.uniform_in(-1.0, 0.0);
        }
        frames.push(FrameLikelihood {
            no_contact: if pressed.is_some() {
                -14.0
            } else {
                rng.uniform_in(-0.5, 0.0)
            },
            points,
            patch: Vec::new(),
        });
    }
    (times, frames)
}

/// Every stretch's beliefs, in order, and the stretches' first frames.
fn smoothed_in_stretches(
    m: &TemporalModel,
    (times, frames): (&[f64], &[FrameLikelihood]),
    limit_bytes: usize,
) -> (Vec<Belief>, Vec<usize>) {
    use crate::core::over_time::stretches::StretchSmoother;
    let mut smoother = StretchSmoother::new(m, limit_bytes);
    let mut out = Vec::new();
    let mut firsts = Vec::new();
    let mut take = |stretch: crate::core::over_time::stretches::Stretch, out: &mut Vec<Belief>| {
        assert_eq!(stretch.first, out.len(), "stretches follow one another");
        firsts.push(stretch.first);
        out.extend((0..stretch.len()).map(|i| stretch.belief(i).unwrap()));
    };
    for (t, f) in times.iter().zip(frames) {
        if let Some(piece) = smoother.push(*t, f.clone()).unwrap() {
            take(piece.smooth(m), &mut out);
        }
        assert!(smoother.held_bytes() <= limit_bytes);
    }
    for piece in smoother.finish().unwrap() {
        take(piece.smooth(m), &mut out);
    }
    (out, firsts)
}

/// Smoothing in stretches cut where the filter is sure of no contact
/// gives the whole recording's smoother's beliefs (to the f32 store's
/// precision); cuts forced by a small store inside long presses move the
/// contact probability by little, and the store never passes its limit.
#[test]
fn stretches_match_the_whole_recordings_smoother() {
    let m = model(
        4,
        TemporalSettings {
            step_secs: 0.0,
            ..TemporalSettings::default()
        },
    );
    let (times, frames) = long_recording(6000, 5);
    let mut whole = Smoother::new(&m);
    for (t, f) in times.iter().zip(&frames) {
        whole.push(*t, f).unwrap();
    }
    let whole = whole.finish().unwrap();
    let worst = |got: &[Belief]| {
        assert_eq!(got.len(), whole.len());
        got.iter()
            .zip(&whole)
            .map(|(g, w)| {
                let d = (g.no_contact - w.no_contact).abs();
                g.points
                    .iter()
                    .zip(&w.points)
                    .map(|(a, b)| (a - b).abs())
                    .fold(d, f64::max)
            })
            .fold(0.0, f64::max)
    };
    let (quiet, firsts) = smoothed_in_stretches(&m, (&times, &frames), 1 << 30);
    assert!(firsts.len() >= 4, "cut at the quiet between presses: {firsts:?}");
    for &first in &firsts[1..] {
        assert!(whole[first - 1].no_contact > 0.99, "cut at {first} within a press");
    }
    assert!(worst(&quiet) < 1e-5, "quiet cuts: {}", worst(&quiet));
    // About 150 frames in store: cuts inside the 600-frame presses.
    let (forced, firsts) = smoothed_in_stretches(&m, (&times, &frames), 150 * 128);
    assert!(firsts.len() > 40, "{}", firsts.len());
    assert!(worst(&forced) < 1e-3, "forced cuts: {}", worst(&forced));
    // A limit that cannot hold a few frames is refused.
    let mut tiny = crate::core::over_time::stretches::StretchSmoother::new(&m, 100);
    assert!(matches!(
        tiny.push(0.0, frames[0].clone()),
        Err(TemporalError::TooLarge { .. })
    ));
}

/// Frames closer together than the model's step share one state: the
/// smoother (whole, and in stretches) gives each frame the belief that
/// the model with a step per frame gives the pair's summed evidence.
#[test]
fn frames_within_a_step_share_its_state() {
    let (times, frames) = long_recording(3001, 7);
    let with_step = |step_secs: f64| {
        model(
            4,
            TemporalSettings {
                step_secs,
                ..TemporalSettings::default()
            },
        )
    };
    let (stepped, plain) = (with_step(0.002), with_step(0.0));
    let mut pair_times = Vec::new();
    let mut pairs = Vec::new();
    for (t, f) in times.chunks(2).zip(frames.chunks(2)) {
        let mut sum = f[0].clone();
        if let Some(second) = f.get(1) {
            sum.no_contact += second.no_contact;
            for (a, b) in sum.points.iter_mut().zip(&second.points) {
                *a += b;
            }
        }
        pair_times.push(t[0]);
        pairs.push(sum);
    }
    let whole = |m: &TemporalModel, times: &[f64], frames: &[FrameLikelihood]| {
        let mut s = Smoother::new(m);
        for (t, f) in times.iter().zip(frames) {
            s.push(*t, f).unwrap();
        }
        s.finish().unwrap()
    };
    let expected = whole(&plain, &pair_times, &pairs);
    let same = |got: &[Belief], what: &str| {
        assert_eq!(got.len(), times.len(), "{what}");
        for (i, b) in got.iter().enumerate() {
            let e = &expected[i / 2];
            assert!((b.no_contact - e.no_contact).abs() < 1e-12, "{what}, frame {i}");
            for (x, y) in b.points.iter().zip(&e.points) {
                assert!((x - y).abs() < 1e-12, "{what}, frame {i}: {b:?} vs {e:?}");
            }
        }
    };
    same(&whole(&stepped, &times, &frames), "whole");
    let (quiet, firsts) = smoothed_in_stretches(&stepped, (&times, &frames), 1 << 30);
    let (quiet_pairs, pair_firsts) = smoothed_in_stretches(&plain, (&pair_times, &pairs), 1 << 30);
    assert!(firsts.len() >= 2, "{firsts:?}");
    assert_eq!(firsts.iter().map(|f| f / 2).collect::<Vec<_>>(), pair_firsts);
    for (i, b) in quiet.iter().enumerate() {
        assert_eq!(b, &quiet_pairs[i / 2], "stretches, frame {i}");
    }
    // Steps gathered ahead of the filter (as a recording's frames are,
    // beside it) give the same stretches, bit for bit.
    let mut ahead = crate::core::over_time::stretches::StretchSmoother::new(&stepped, 1 << 30);
    let mut preparer = crate::core::over_time::stretches::StepPreparer::new(&stepped);
    let mut prepared = Vec::new();
    for (t, f) in times.iter().zip(&frames) {
        if let Some(step) = preparer.push(*t, f.clone()).unwrap() {
            prepared.extend(ahead.push_step(step).unwrap());
        }
    }
    prepared.extend(
        preparer
            .finish()
            .map(|step| ahead.push_step(step).unwrap())
            .into_iter()
            .flatten(),
    );
    prepared.extend(ahead.finish().unwrap());
    let from_prepared: Vec<Belief> = prepared
        .into_iter()
        .flat_map(|piece| {
            let stretch = piece.smooth(&stepped);
            (0..stretch.len()).map(move |i| stretch.belief(i).unwrap())
        })
        .collect();
    assert_eq!(from_prepared, quiet, "steps prepared ahead");
    let mut refusing = crate::core::over_time::stretches::StepPreparer::new(&stepped);
    refusing.push(0.0, frames[0].clone()).unwrap();
    assert!(matches!(
        refusing.push(-0.001, frames[1].clone()),
        Err(TemporalError::BadTime { frame: 1, .. })
    ));
    // A frame whose time goes back is named, step or not.
    let mut s = Smoother::new(&stepped);
    s.push(0.0, &frames[0]).unwrap();
    s.push(0.001, &frames[1]).unwrap();
    assert!(matches!(
        s.push(0.0005, &frames[2]),
        Err(TemporalError::BadTime { frame: 2, .. })
    ));
}

/// A contact that cannot move, begin or end: two frames filtered one by
/// one and their patches' terms added into one step give the same
/// belief and offsets (the Gaussian terms telescope, the charge beyond
/// the patch's reach included).
#[test]
fn a_step_adds_the_patches_terms_exactly() {
    use crate::core::numerics::rng::Rng;
    let still = TemporalSettings {
        onset_per_s: 0.0,
        release_per_s: 0.0,
        slide_m_per_sqrt_s: 0.0,
        jump_per_s: 0.0,
        step_secs: 0.0,
    };
    let mut m = model(4, still);
    m.window_m = vec![0.01; 4];
    let mut rng = Rng::new(5);
    let frame = |rng: &mut Rng| {
        let patch: Vec<PatchInformation> = (0..4)
            .map(|_| {
                let (m11, m22) = (rng.uniform_in(1e3, 1e6), rng.uniform_in(1e3, 1e6));
                let m12 = rng.uniform_in(-0.9, 0.9) * (m11 * m22).sqrt();
                // Means up to three windows out: some beyond the reach.
                let (y1, y2) = (rng.uniform_in(-0.03, 0.03), rng.uniform_in(-0.03, 0.03));
                PatchInformation {
                    point: rng.uniform_in(-20.0, 0.0),
                    information: [m11, m12, m22],
                    shift: [m11 * y1 + m12 * y2, m12 * y1 + m22 * y2],
                }
            })
            .collect();
        FrameLikelihood {
            no_contact: rng.uniform_in(-20.0, 0.0),
            points: patch.iter().map(|p| p.point).collect(),
            patch,
        }
    };
    for _ in 0..20 {
        let (a, b) = (frame(&mut rng), frame(&mut rng));
        let mut one_by_one = Filter::new(&m);
        one_by_one.step(0.0, &a).unwrap();
        let apart = one_by_one.step(0.001, &b).unwrap().clone();
        let mut joined = StepJoiner::default();
        assert!(joined.push(0.002, 0.0, a).unwrap().is_none());
        assert!(joined.push(0.002, 0.001, b).unwrap().is_none());
        let step = joined.finish().unwrap();
        assert_eq!(step.frames, 2);
        let together = Filter::new(&m).step(step.t_secs, &step.likelihood).unwrap().clone();
        assert!((apart.no_contact - together.no_contact).abs() < 1e-9);
        for k in 0..4 {
            assert!(
                (apart.points[k] - together.points[k]).abs() < 1e-9,
                "{apart:?} vs {together:?}"
            );
            let (x, y) = (apart.offsets[k], together.offsets[k]);
            for (p, q) in x.precision.iter().zip(y.precision).chain(x.shift.iter().zip(y.shift)) {
                assert!((p - q).abs() <= 1e-9 * p.abs().max(1.0), "{x:?} vs {y:?}");
            }
        }
    }
}
