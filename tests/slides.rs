//! Contacts that slide, smoothed: a slide that the recording's random walk
//! holds in one place is followed by the press fit, and a press the
//! recording leaves for a few frames, or for a slip on the next link, is
//! fitted whole, and a press's rests are fitted held still; a rest the
//! recording walks off takes its press's fit.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use crate::common;

use common::run_out;

/// A generated slide on `link` (`synth` seed `seed`, in a folder named
/// `folder`) estimated smoothed at surface seed `surface_seed`: the
/// summary's all-frames row, and the whole output.
fn smoothed_slide(folder: &str, link: &str, seed: &str, surface_seed: &str) -> (Vec<f64>, String) {
    smoothed_slide_with(folder, link, seed, surface_seed, &[])
}

/// [`smoothed_slide`] with `more` options after its own (`--out`, say).
fn smoothed_slide_with(folder: &str, link: &str, seed: &str, surface_seed: &str, more: &[&str]) -> (Vec<f64>, String) {
    let path = common::temp_dir(folder).join("slide.json");
    common::synth_slide(&path, link, seed);
    let mut args = vec![
        "estimate",
        path.to_str().unwrap(),
        "--temporal",
        "smooth",
        "--seed",
        surface_seed,
    ];
    args.extend_from_slice(more);
    let (ok, out, err) = run_out(&args);
    assert!(ok, "{err}");
    (common::all_row(&out), out)
}

/// The median of the estimated over the true path of the presses that
/// slid, from `estimate`'s summary line `slides: … estimated path / true
/// path: median R …`.
fn median_path_ratio(out: &str) -> f64 {
    let line = out.lines().find(|l| l.starts_with("slides:")).unwrap();
    let (_, after) = line.split_once("true path: median ").unwrap();
    after.split_whitespace().next().unwrap().parse().unwrap()
}

/// A generated link 5 session whose first press slides 4 cm at a `μ_k` of
/// 0.3–0.6 while the smoother, at 1 cm/√s, holds one place 8 cm off.
#[test]
fn a_slide_the_smoother_holds_in_one_place_is_followed() {
    let (row, out) = smoothed_slide("slides", "lwr_5_link", "1", "0");
    let (position_mm, force_n) = (row[0], row[2]);
    // Measured 5.7 mm and 0.30 N (9.0 mm and 0.36 N with hops between
    // links 4 and 5 bridged for 25 ms only); without the fit followed at a
    // faster slide, 16.1 mm and 1.11 N (docs/validation.md, *Sliding
    // contacts*).
    assert!(position_mm <= 10.0, "{out}");
    assert!(force_n <= 0.8, "{out}");
}

/// A generated link 5 session (`--seed 3`) whose slides the smoother
/// leaves for a frame or two at a time (to another link, or to another
/// place it then holds): each press is fitted across such hops.
#[test]
fn a_press_the_smoother_leaves_for_a_few_frames_is_fitted_whole() {
    let (row, out) = smoothed_slide("slides_hops", "lwr_5_link", "3", "0");
    let position_mm = row[0];
    // Measured 11.8 mm (3.3 mm since rests are also fitted held still);
    // with each run of frames on one link fitted as a press of its own,
    // 17.9 mm (docs/validation.md, *Sliding contacts*).
    assert!(position_mm <= 15.0, "{out}");
}

/// A generated link 6 session (`--seed 1`) whose second press slips for
/// 0.55 s with a drag outside the smoother's friction cone: the smoother
/// puts the whole slip on link 5, 51 mm off. Bridged across that hop,
/// the press is fitted whole with kinetic friction, and stays on link 6.
#[test]
fn a_slip_the_smoother_puts_on_the_next_link_is_fitted_with_its_press() {
    let (row, out) = smoothed_slide("slides_next_link", "lwr_6_link", "1", "0");
    let (p90_mm, link_right_percent) = (row[1], row[4]);
    // Measured 1.2 mm at p90 and the link right in 99 % of the contact
    // frames; with hops of 25 ms bridged and no longer, 53.3 mm and 60 %
    // (docs/validation.md, *Slips that the smoother puts on the next link*).
    assert!(p90_mm <= 10.0, "{out}");
    assert!(link_right_percent >= 95.0, "{out}");
}

/// A generated link 4 session (`--seed 2`) whose slip at 3.2 s the
/// smoother puts on link 6 for 0.3 s: four sensed joints feel link 4 and
/// six link 6, and the press is bridged across that hop too (not across
/// one to link 3, which three feel).
#[test]
fn a_slip_the_smoother_puts_on_link_6_is_fitted_with_its_link_4_press() {
    let (row, out) = smoothed_slide("slides_link_4", "lwr_4_link", "2", "0");
    let (position_mm, link_right_percent) = (row[0], row[4]);
    // Measured 2.5 mm and the link right in 100 % of the contact frames;
    // with hops to link 4 bridged for 25 ms only, 11.8 mm and 88 %
    // (docs/validation.md, *Long hops to and from link 4*).
    assert!(position_mm <= 6.0, "{out}");
    assert!(link_right_percent >= 95.0, "{out}");
}

/// A generated link 4 session (`--seed 3`) whose presses rest between
/// slides: their rests are fitted held still as well, as on the links
/// that more joints feel, and the cheaper fit is kept.
#[test]
fn a_link_4_slide_is_fitted_with_its_rests_held_still() {
    let (_, out) = smoothed_slide("slides_link_4_rests", "lwr_4_link", "3", "0");
    // Measured 1.05, two of its four slides within 20 % of their path;
    // with rests held still only on links that five or more joints feel,
    // 1.46 and none (docs/validation.md, *Rests held still on link 4*).
    let ratio = median_path_ratio(&out);
    assert!((ratio - 1.0).abs() <= 0.2, "{out}");
}

#[test]
fn a_link_5_slide_is_paced_by_its_own_frames() {
    let (_, out) = smoothed_slide("slides_link_5_pace", "lwr_5_link", "1", "0");
    // Measured 1.07, two of its three slides within 20 % of their path;
    // with each slipping frame's pace fitted through the rests around
    // it too, 1.95 and one (docs/validation.md, *A slip's pace from its
    // own frames*).
    let ratio = median_path_ratio(&out);
    assert!((ratio - 1.0).abs() <= 0.2, "{out}");
}

/// The same link 5 session at surface seed 2: its press at 3.35 s rests,
/// slides 2 cm and rests again, and while it slips its frames alone lie
/// 4 cm off (their drag exceeds the friction cone), the smoother's
/// track with them; the fit started from the two rests, which the frames
/// alone pin within millimetres, finds the slide.
#[test]
fn a_slide_between_two_rests_is_fitted_from_the_rests() {
    let (row, out) = smoothed_slide("slides_rests", "lwr_5_link", "3", "2");
    // Measured 2.0 mm; without the start from the rests, 17.6 mm
    // (docs/validation.md, *A slide between two rests*).
    let position_mm = row[0];
    assert!(position_mm <= 8.0, "{out}");
}

/// A generated link 7 session (`--seed 3`) whose second press slides,
/// then sticks at 2.54–2.80 s on the flange's side, 1 mm below its end
/// face: the smoother's place lies on the edge between them, 1.8 mm off,
/// where a frictionless push misses each frame at χ² about 11,000, and
/// the press check rejects it. The press's frictionless fit from there
/// lands on the true place, explaining the frames within a few a frame of
/// their own contacts, and replaces the recording rather than each frame
/// taking its own contact.
#[test]
fn a_rest_the_recording_walks_off_takes_its_press_fit() {
    let json = common::temp_dir("slides_flange_rest_out").join("est.jsonl");
    let (_, out) = smoothed_slide_with(
        "slides_flange_rest",
        "lwr_7_link",
        "3",
        "0",
        &["--out", json.to_str().unwrap()],
    );
    let rest: Vec<(String, f64)> = common::json_lines(&json)
        .iter()
        .filter(|line| (2.55..=2.75).contains(&line["t"].as_f64().unwrap()))
        .map(|line| {
            let link = line["link"].as_str().unwrap_or("none").to_owned();
            (
                link,
                line["truth"]["position_error_m"].as_f64().unwrap_or(f64::INFINITY),
            )
        })
        .collect();
    assert_eq!(rest.len(), 41, "{out}");
    // Measured 0.4 mm at most, every frame on link 7; each frame's own
    // contact instead: 6 of the 41 on link 5, 70 mm off, and the rest
    // hopping 1–10 mm from frame to frame (docs/validation.md, *A rest the
    // recording walks off*).
    for (link, error_m) in &rest {
        assert_eq!(link, "lwr_7_link", "{rest:?}");
        assert!(*error_m <= 0.005, "{rest:?}");
    }
}

/// The `../shared` link 6 slide at three surface seeds.
#[test]
#[ignore = "needs ../shared"]
fn the_shared_link_6_slide_is_placed_at_every_surface_seed() {
    // Measured 5.8 / 18.9 / 9.7 mm at seeds 0 / 1 / 2; before the fit
    // followed at a faster slide, 7.7 / 40.8 / 9.8 mm.
    for seed in ["0", "1", "2"] {
        let (ok, out, err) = run_out(&[
            "estimate",
            "../shared/sessions/lwr4plus_slide_example.session.json",
            "--temporal",
            "smooth",
            "--seed",
            seed,
        ]);
        assert!(ok, "{err}");
        let position_mm = common::all_row(&out)[0];
        assert!(position_mm <= 25.0, "seed {seed}: {out}");
    }
}
