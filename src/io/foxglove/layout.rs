//! The Foxglove layout shipped as `assets/foxglove-layout.json`
//! (`proprioscope export-assets` writes it): the 3-D panel with the arm,
//! its heatmap and arrows; plots of the joint torques, of the force and
//! of the contact; Foxglove's own timeline below.

use serde_json::{Value, json};

use super::{ARM_TOPIC, ARROWS_TOPIC, HEATMAP_TOPIC, NUMBERS_TOPIC, TRANSFORMS_TOPIC};

/// Where the layout ships in the repository.
pub const LAYOUT_PATH: &str = "assets/foxglove-layout.json";

/// How many joints' torques the torque plot draws (`/joint_states`'
/// `effort[0]` to `effort[6]`: a 7-joint arm's).
const PLOTTED_JOINTS: usize = 7;

/// A plotted series: `topic.field`, by the messages' receive time.
fn series(path: &str, label: &str) -> Value {
    json!({"value": path, "enabled": true, "timestampMethod": "receiveTime", "label": label})
}

/// A plot panel.
fn plot(title: &str, paths: &[Value]) -> Value {
    json!({
        "title": title,
        "paths": paths,
        "showXAxisLabels": true,
        "showYAxisLabels": true,
        "showLegend": true,
        "legendDisplay": "floating",
        "isSynced": true,
        "xAxisVal": "timestamp",
    })
}

/// The layout, as Foxglove imports it (Layouts → Import from file).
#[must_use]
pub fn layout() -> Value {
    let torques: Vec<Value> = (0..PLOTTED_JOINTS)
        .map(|k| series(&format!("/joint_states.effort[{k}]"), &format!("τ{} [N·m]", k + 1)))
        .collect();
    let numbers = |field: &str| format!("{NUMBERS_TOPIC}.{field}");
    json!({
        "configById": {
            "3D!proprioscope": {
                "topics": {
                    ARM_TOPIC: {"visible": true},
                    HEATMAP_TOPIC: {"visible": true},
                    ARROWS_TOPIC: {"visible": true},
                    TRANSFORMS_TOPIC: {"visible": true},
                    "/proprioscope/region": {"visible": false},
                    "/robot_description": {"visible": false},
                },
                "scene": {"transforms": {"showLabel": false, "axisScale": 0.5}},
                "cameraState": {
                    "perspective": true,
                    "distance": 2.2,
                    "phi": 60.0,
                    "thetaOffset": 45.0,
                    "targetOffset": [0.0, 0.0, 0.5],
                    "target": [0.0, 0.0, 0.0],
                    "targetOrientation": [0.0, 0.0, 0.0, 1.0],
                    "fovy": 45.0,
                    "near": 0.01,
                    "far": 100.0,
                },
            },
            "Plot!torques": plot("Joint torques [N·m]", &torques),
            "Plot!force": plot("Force [N]", &[
                series(&numbers("force_newtons"), "estimated"),
                series(&numbers("force_error_newtons"), "error against the truth"),
            ]),
            "Plot!contact": plot("Contact", &[
                series(&numbers("contact_probability"), "P(contact)"),
                series(&numbers("verdict"), "verdict (0 none, 1 contact, 2 poorly explained)"),
                series(&numbers("position_error_m"), "position error [m]"),
            ]),
        },
        "globalVariables": {},
        "userNodes": {},
        "playbackConfig": {"speed": 1.0},
        "layout": {
            "direction": "row",
            "first": "3D!proprioscope",
            "second": {
                "direction": "column",
                "first": "Plot!torques",
                "second": {"direction": "column", "first": "Plot!force", "second": "Plot!contact"},
                "splitPercentage": 34.0,
            },
            "splitPercentage": 60.0,
        },
    })
}

/// The layout file's text.
#[must_use]
pub fn layout_text() -> String {
    let mut text = serde_json::to_string_pretty(&layout()).unwrap_or_default();
    text.push('\n');
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_layout_is_what_the_program_writes_today() {
        let shipped = include_str!("../../../assets/foxglove-layout.json");
        assert!(
            shipped == layout_text(),
            "{LAYOUT_PATH} is stale: run `cargo run -- export-assets`"
        );
    }

    /// The panel ids at the leaves of a layout tree.
    fn leaves(v: &Value, out: &mut Vec<String>) {
        match v {
            Value::String(s) => out.push(s.clone()),
            Value::Object(o) => {
                for key in ["first", "second"] {
                    if let Some(child) = o.get(key) {
                        leaves(child, out);
                    }
                }
            }
            _ => {}
        }
    }

    #[test]
    fn every_panel_in_the_layout_is_configured() {
        let l = layout();
        let mut ids = Vec::new();
        leaves(&l["layout"], &mut ids);
        assert_eq!(ids.len(), 4);
        for id in ids {
            assert!(l["configById"].get(&id).is_some(), "{id}");
        }
    }
}
