//! Tests of [`super`]: `scene.rs`.

use super::*;

const MINIMAL: &str = r#"{"version": 1, "robot": "lwr4plus", "q": [0, 0, 0, 0, 0, 0, 0]}"#;

#[test]
fn defaults_fill_missing_optional_fields() {
    let s = Scene::parse(MINIMAL, Path::new("m.json")).unwrap();
    assert_eq!(s.surface_points, 5000);
    assert_eq!(s.estimator.mode, Mode::Exact);
    assert_eq!(s.estimator.phases.sizes, [200, 1000]);
    assert!(s.push.is_none());
}

#[test]
fn unknown_field_is_rejected_by_name() {
    let text = MINIMAL.replace("\"q\"", "\"surface_pionts\": 3, \"q\"");
    let e = Scene::parse(&text, Path::new("typo.json")).unwrap_err().to_string();
    assert!(e.contains("typo.json") && e.contains("surface_pionts"), "{e}");
}

#[test]
fn nan_is_reported_with_its_place() {
    let text = MINIMAL.replace("[0, 0, 0,", "[0, NaN, 0,");
    let e = Scene::parse(&text, Path::new("nan.json")).unwrap_err().to_string();
    assert!(e.contains("nan.json:1:") && e.contains("NaN"), "{e}");
}

#[test]
fn wrong_joint_count_names_the_field_and_the_joints() {
    let text = MINIMAL.replace("[0, 0, 0, 0, 0, 0, 0]", "[0, 0, 0]");
    let e = Scene::parse(&text, Path::new("short.json"))
        .unwrap()
        .load(Path::new("short.json"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("short.json") && e.contains("'q'") && e.contains("expected 7") && e.contains("got 3"),
        "{e}"
    );
}

#[test]
fn invalid_values_name_their_field() {
    let cases = [
        (
            r#""push": {"link": "lwr_2_link", "point_world": [0, 0, 0.4]}, "q""#,
            "push",
        ),
        (
            r#""estimator": {"force_min_newtons": 5, "force_max_newtons": 2}, "q""#,
            "force_min_newtons",
        ),
        (
            r#""estimator": {"sigma_newton_metres": [0.1, -1]}, "q""#,
            "sigma_newton_metres",
        ),
        (r#""estimator": {"friction": -0.2}, "q""#, "estimator.friction"),
        (r#""version": 2, "q""#, "version"),
    ];
    for (insert, field) in cases {
        let text = MINIMAL.replace("\"q\"", insert).replace(
            r#"{"version": 1, "robot": "lwr4plus", "version": 2"#,
            r#"{"robot": "lwr4plus", "version": 2"#,
        );
        let e = Scene::parse(&text, Path::new("bad.json")).unwrap_err().to_string();
        assert!(e.contains(field), "{insert}: {e}");
    }
}

#[test]
fn push_by_magnitude_follows_the_inward_normal() {
    let text = MINIMAL.replace(
        "\"q\"",
        r#""push": {"link": "lwr_7_link", "point_in_link": [0.0, 0.0, 0.0], "force_newtons": 4}, "q""#,
    );
    let loaded = Scene::parse(&text, Path::new("x.json"))
        .unwrap()
        .load(Path::new("x.json"))
        .unwrap();
    let push = loaded.push.unwrap();
    // The flange's top face: the inward normal points down.
    assert!(
        (push.force_world - DVec3::new(0.0, 0.0, -4.0)).length() < 1e-6,
        "{}",
        push.force_world
    );
}

#[test]
fn round_trip_through_json() {
    let s = Scene::parse(MINIMAL, Path::new("m.json")).unwrap();
    let again = Scene::parse(&s.to_json().unwrap(), Path::new("m.json")).unwrap();
    assert_eq!(s, again);
}
