//! The rigid-body dynamics against the oracles in `../shared/oracle/`
//! (Pinocchio 4.1 on the real robot descriptions, cross-checked with
//! MuJoCo): `M`, `C q̇ + g`, `g`, inverse dynamics and the Coriolis matrix
//! at 40 states per robot, and the regressor times the URDF's parameters.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use crate::common;

use proprioscope::core::robot::dynamics::RigidBodies;
use proprioscope::io::urdf::{UrdfOptions, load_urdf};
use serde::Deserialize;

#[derive(Deserialize)]
struct Oracle {
    meta: Meta,
    states: Vec<State>,
}

#[derive(Deserialize)]
struct Meta {
    urdf: String,
    joint_names: Vec<String>,
}

#[derive(Deserialize)]
struct State {
    q: Vec<f64>,
    qdot: Vec<f64>,
    qddot: Vec<f64>,
    #[serde(rename = "M")]
    mass: Vec<Vec<f64>>,
    nle: Vec<f64>,
    g: Vec<f64>,
    tau: Vec<f64>,
    #[serde(rename = "C")]
    coriolis: Vec<Vec<f64>>,
}

/// Largest difference relative to the oracle's scale (its largest entry, at least 1).
fn worst(ours: &[f64], theirs: &[f64]) -> f64 {
    assert_eq!(ours.len(), theirs.len());
    let scale = theirs.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
    ours.iter()
        .zip(theirs)
        .fold(0.0, |m, (a, b)| m.max((a - b).abs() / scale))
}

fn check(robot_name: &str) {
    let path = common::shared().join(format!("oracle/{robot_name}_dynamics.json"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let oracle: Oracle = serde_json::from_str(&text).unwrap();
    let urdf = common::shared().join(&oracle.meta.urdf);
    let options = UrdfOptions {
        meshes: proprioscope::io::urdf::MeshSelection::None,
        ..UrdfOptions::default()
    };
    let robot = load_urdf(&urdf, &options).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(robot.sensed_names(), oracle.meta.joint_names, "{robot_name}");
    let bodies = RigidBodies::new(&robot);
    let parameters = bodies.parameters();
    assert_eq!(oracle.states.len(), 40);
    // The oracle is written to 10 significant digits.
    let tolerance = 1e-8;
    for (i, s) in oracle.states.iter().enumerate() {
        let flat = |m: &Vec<Vec<f64>>| m.iter().flatten().copied().collect::<Vec<_>>();
        let checks = [
            ("M", bodies.mass_matrix(&s.q).unwrap(), flat(&s.mass)),
            ("nle", bodies.nonlinear_effects(&s.q, &s.qdot).unwrap(), s.nle.clone()),
            ("g", bodies.gravity(&s.q).unwrap(), s.g.clone()),
            (
                "rnea",
                bodies.inverse_dynamics(&s.q, &s.qdot, &s.qddot).unwrap(),
                s.tau.clone(),
            ),
            ("C", bodies.coriolis_matrix(&s.q, &s.qdot).unwrap(), flat(&s.coriolis)),
        ];
        for (what, ours, theirs) in checks {
            let error = worst(&ours, &theirs);
            assert!(
                error < tolerance,
                "{robot_name} state {i} {what}: relative error {error:e}\n{ours:?}\n{theirs:?}"
            );
        }
        let y = bodies.regressor(&s.q, &s.qdot, &s.qddot).unwrap();
        let n = s.q.len();
        let from_regressor: Vec<f64> = (0..n)
            .map(|row| {
                (0..parameters.len())
                    .map(|c| y[row * parameters.len() + c] * parameters[c])
                    .sum()
            })
            .collect();
        let error = worst(&from_regressor, &s.tau);
        assert!(
            error < tolerance,
            "{robot_name} state {i} Y·π: relative error {error:e}"
        );
    }
}

#[test]
#[ignore = "needs ../shared"]
fn lwr4plus_dynamics_oracle() {
    check("lwr4plus");
}

#[test]
#[ignore = "needs ../shared"]
fn iiwa14_dynamics_oracle() {
    check("iiwa14");
}

#[test]
#[ignore = "needs ../shared"]
fn panda_dynamics_oracle() {
    check("panda");
}
