//! Where a press between two rests starts.

use super::*;

/// Which frames of a 25-frame press [`rests_at_ends`] pins, its frames
/// alone at `place(k)` (link frame, m).
fn rest_frames(place: impl Fn(usize) -> DVec3) -> Option<Vec<usize>> {
    let in_link: Vec<Option<DVec3>> = (0..25).map(|k| Some(place(k))).collect();
    rests_at_ends(&in_link)
}

#[test]
fn a_press_between_two_rests_starts_from_its_rests_alone() {
    let a = DVec3::new(0.03, 0.01, 0.06);
    // A millimetre or two of a frame alone's jitter.
    let jitter = |k: usize| DVec3::new(0.0, 0.0, 1e-3 * ((k * 7) % 3) as f64);
    // Rests at `a` (frames 0-3) and 2 cm on (frames 20-24), slipping
    // frames alone 4 cm off between (frame 4 among the first fifth).
    let slide = |k: usize| {
        jitter(k)
            + match k {
                0..=3 => a,
                20.. => a + DVec3::new(0.0, 0.02, 0.0),
                _ => a + DVec3::new(0.04, 0.0, 0.0),
            }
    };
    assert_eq!(rest_frames(slide), Some(vec![0, 1, 2, 3, 20, 21, 22, 23, 24]));
    // A press that holds its place: no slide between rests to start.
    assert_eq!(rest_frames(|k| a + jitter(k)), None);
    // Rests 8 mm apart: within a rest's width, no start either.
    assert_eq!(
        rest_frames(|k| a + jitter(k) + DVec3::new(0.0, if k >= 20 { 0.008 } else { 0.0 }, 0.0)),
        None
    );
    // Too few frames at the first rest: two of the first five, the other
    // three scattered 3 cm apart.
    let few = |k: usize| match k {
        2..=4 => a + DVec3::new(0.03 * k as f64, 0.0, 0.0),
        _ => slide(k),
    };
    assert_eq!(rest_frames(few), None);
    // Three, the rest of the first five slipping: the three are the rest.
    let three = |k: usize| if k == 3 { slide(4) } else { slide(k) };
    assert_eq!(rest_frames(three), Some(vec![0, 1, 2, 20, 21, 22, 23, 24]));
    // Frames without a place of their own on the link do not count.
    let missing: Vec<Option<DVec3>> = (0..25).map(|k| (k != 1 && k != 2).then(|| slide(k))).collect();
    assert_eq!(rests_at_ends(&missing), None);
}
