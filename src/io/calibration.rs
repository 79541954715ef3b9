//! Calibration files (`*.calib.json`, `"format": "proprioscope-calibration"`,
//! version 1): what `calibrate` learned of a robot's torques, for
//! `estimate --calibration FILE` on other recordings of the same robot.
//!
//! Unknown fields are rejected; every number is checked to be finite and
//! every per-joint list to have one value per joint.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::core::over_time::calibration::{Calibration, STICTION_SPEED_RAD_S};

/// The `format` field.
pub const CALIBRATION_FORMAT: &str = "proprioscope-calibration";
/// The version this program reads and writes.
pub const CALIBRATION_VERSION: u32 = 1;

/// A calibration file as stored.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationFile {
    /// Always [`CALIBRATION_FORMAT`].
    pub format: String,
    /// Always 1.
    pub version: u32,
    /// The robot as the recording named it (a built-in name or a URDF path).
    pub robot: String,
    /// The sensed joints, in the order of every per-joint list.
    pub joints: Vec<String>,
    /// The observer's gain K, 1/s; `null`: the torques carry no lag.
    pub observer_gain_per_s: Option<f64>,
    /// Link names, ten inertial corrections each in `inertial_corrections`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub links: Vec<String>,
    /// Model minus arm, ten per link (m, m·c, I about the link origin);
    /// empty when no inertial correction was fitted.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub inertial_corrections: Vec<f64>,
    /// Coulomb friction per joint, N·m.
    pub coulomb_nm: Vec<f64>,
    /// The Coulomb term's lead per joint, s (absent: none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub coulomb_lead_secs: Vec<f64>,
    /// The Coulomb term's transition speed per joint, rad/s (absent:
    /// [`STICTION_SPEED_RAD_S`] for every joint).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub coulomb_switch_rad_s: Vec<f64>,
    /// Viscous friction per joint, N·m·s/rad.
    pub viscous_nms_per_rad: Vec<f64>,
    /// Constant offset per joint, N·m.
    pub offset_nm: Vec<f64>,
    /// Residual RMS per joint after the correction, on free frames, N·m.
    pub sigma_nm: Vec<f64>,
    /// The residual's correlation time per joint, s.
    pub correlation_secs: Vec<f64>,
    /// Residual RMS per joint before the correction, N·m.
    pub rms_before_nm: Vec<f64>,
    /// Residual RMS per joint after the correction, still lagged, N·m.
    pub rms_after_nm: Vec<f64>,
    /// Frames the fit read.
    pub frames_read: usize,
    /// Of which free of contact.
    pub free_frames: usize,
    /// Whether the fit found a model error (else every correction is 0).
    pub found: bool,
}

/// Why a calibration file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationFileError {
    /// The file could not be read.
    #[error("{path}: cannot read the calibration: {cause}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The system's reason.
        cause: std::io::Error,
    },
    /// The file could not be written.
    #[error("{path}: cannot write the calibration: {cause}")]
    Write {
        /// The file.
        path: PathBuf,
        /// The system's reason.
        cause: std::io::Error,
    },
    /// Malformed JSON.
    #[error("{path}: not a calibration file: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The parser's message.
        message: String,
    },
    /// A field is wrong.
    #[error("{path}: field '{field}': {message}")]
    Field {
        /// The file.
        path: PathBuf,
        /// The field.
        field: &'static str,
        /// What is wrong.
        message: String,
    },
}

impl CalibrationFile {
    /// The file form of `calibration` for `robot` (`links`: every link's
    /// name, in the robot's order).
    #[must_use]
    pub fn new(calibration: &Calibration, robot: &str, links: Vec<String>) -> Self {
        Self {
            format: CALIBRATION_FORMAT.to_owned(),
            version: CALIBRATION_VERSION,
            robot: robot.to_owned(),
            joints: calibration.joints.clone(),
            observer_gain_per_s: calibration.observer_gain_per_s,
            links: if calibration.inertial_corrections.is_empty() {
                Vec::new()
            } else {
                links
            },
            inertial_corrections: calibration.inertial_corrections.clone(),
            coulomb_nm: calibration.coulomb_nm.clone(),
            coulomb_lead_secs: calibration.coulomb_lead_secs.clone(),
            coulomb_switch_rad_s: calibration.coulomb_switch_rad_s.clone(),
            viscous_nms_per_rad: calibration.viscous_nms_per_rad.clone(),
            offset_nm: calibration.offset_nm.clone(),
            sigma_nm: calibration.sigma_nm.clone(),
            correlation_secs: calibration.correlation_secs.clone(),
            rms_before_nm: calibration.rms_before_nm.clone(),
            rms_after_nm: calibration.rms_after_nm.clone(),
            frames_read: calibration.frames_read,
            free_frames: calibration.free_frames,
            found: calibration.found,
        }
    }

    /// The calibration it holds, checked.
    pub fn calibration(&self, path: &Path) -> Result<Calibration, CalibrationFileError> {
        let field = |field: &'static str, message: String| CalibrationFileError::Field {
            path: path.to_owned(),
            field,
            message,
        };
        if self.format != CALIBRATION_FORMAT {
            return Err(field(
                "format",
                format!("'{}', expected '{CALIBRATION_FORMAT}'", self.format),
            ));
        }
        if self.version != CALIBRATION_VERSION {
            return Err(field(
                "version",
                format!("{}, this program reads {CALIBRATION_VERSION}", self.version),
            ));
        }
        let n = self.joints.len();
        if n == 0 {
            return Err(field("joints", "empty".to_owned()));
        }
        let lists: [(&'static str, &[f64]); 7] = [
            ("coulomb_nm", &self.coulomb_nm),
            ("viscous_nms_per_rad", &self.viscous_nms_per_rad),
            ("offset_nm", &self.offset_nm),
            ("sigma_nm", &self.sigma_nm),
            ("correlation_secs", &self.correlation_secs),
            ("rms_before_nm", &self.rms_before_nm),
            ("rms_after_nm", &self.rms_after_nm),
        ];
        for (name, values) in lists {
            if values.len() != n {
                return Err(field(name, format!("{} values for {n} joints", values.len())));
            }
            if let Some((i, v)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
                return Err(field(name, format!("value {i} is {v}, not a finite number")));
            }
        }
        let (lead, switch) = self.coulomb_shapes(path)?;
        if let Some((i, v)) = self.sigma_nm.iter().enumerate().find(|(_, v)| **v <= 0.0) {
            return Err(field("sigma_nm", format!("value {i} is {v}, must be > 0")));
        }
        if let Some(k) = self.observer_gain_per_s
            && !(k.is_finite() && k > 0.0)
        {
            return Err(field(
                "observer_gain_per_s",
                format!("{k}: must be a finite number > 0 or null"),
            ));
        }
        if !self.inertial_corrections.is_empty() && self.inertial_corrections.len() != 10 * self.links.len() {
            return Err(field(
                "inertial_corrections",
                format!(
                    "{} values for {} links (ten each)",
                    self.inertial_corrections.len(),
                    self.links.len()
                ),
            ));
        }
        if let Some((i, v)) = self
            .inertial_corrections
            .iter()
            .enumerate()
            .find(|(_, v)| !v.is_finite())
        {
            return Err(field(
                "inertial_corrections",
                format!("value {i} is {v}, not a finite number"),
            ));
        }
        Ok(Calibration {
            joints: self.joints.clone(),
            observer_gain_per_s: self.observer_gain_per_s,
            inertial_corrections: self.inertial_corrections.clone(),
            coulomb_nm: self.coulomb_nm.clone(),
            coulomb_lead_secs: lead,
            coulomb_switch_rad_s: switch,
            viscous_nms_per_rad: self.viscous_nms_per_rad.clone(),
            offset_nm: self.offset_nm.clone(),
            sigma_nm: self.sigma_nm.clone(),
            correlation_secs: self.correlation_secs.clone(),
            rms_before_nm: self.rms_before_nm.clone(),
            rms_after_nm: self.rms_after_nm.clone(),
            frames_read: self.frames_read,
            free_frames: self.free_frames,
            found: self.found,
        })
    }

    /// Each joint's Coulomb lead and transition speed, checked (absent:
    /// no lead, [`STICTION_SPEED_RAD_S`]).
    fn coulomb_shapes(&self, path: &Path) -> Result<(Vec<f64>, Vec<f64>), CalibrationFileError> {
        let n = self.joints.len();
        let lead = if self.coulomb_lead_secs.is_empty() {
            vec![0.0; n]
        } else {
            self.coulomb_lead_secs.clone()
        };
        let switch = if self.coulomb_switch_rad_s.is_empty() {
            vec![STICTION_SPEED_RAD_S; n]
        } else {
            self.coulomb_switch_rad_s.clone()
        };
        for (field, values, lo, hi) in [
            ("coulomb_lead_secs", &lead, 0.0, 10.0),
            ("coulomb_switch_rad_s", &switch, 1e-6, 100.0),
        ] {
            let message = if values.len() == n {
                values
                    .iter()
                    .enumerate()
                    .find(|(_, v)| !(**v >= lo && **v <= hi))
                    .map(|(i, v)| format!("value {i} is {v}, must lie in [{lo}, {hi}]"))
            } else {
                Some(format!("{} values for {n} joints", values.len()))
            };
            if let Some(message) = message {
                return Err(CalibrationFileError::Field {
                    path: path.to_owned(),
                    field,
                    message,
                });
            }
        }
        Ok((lead, switch))
    }

    /// Parses a calibration file's text.
    pub fn parse(text: &str, path: &Path) -> Result<Self, CalibrationFileError> {
        serde_json::from_str(text).map_err(|e| CalibrationFileError::Parse {
            path: path.to_owned(),
            message: e.to_string(),
        })
    }

    /// Reads and checks a calibration file; the links named must be the robot's.
    pub fn read(path: &Path, robot_links: &[String]) -> Result<Calibration, CalibrationFileError> {
        let text = std::fs::read_to_string(path).map_err(|cause| CalibrationFileError::Read {
            path: path.to_owned(),
            cause,
        })?;
        let file = Self::parse(&text, path)?;
        if !file.links.is_empty() && file.links != robot_links {
            return Err(CalibrationFileError::Field {
                path: path.to_owned(),
                field: "links",
                message: format!(
                    "{} are not the robot's links ({}): was it made on another robot?",
                    file.links.join(", "),
                    robot_links.join(", ")
                ),
            });
        }
        file.calibration(path)
    }

    /// Writes it as pretty JSON.
    pub fn write(&self, path: &Path) -> Result<(), CalibrationFileError> {
        let text = serde_json::to_string_pretty(self).map_err(|e| CalibrationFileError::Write {
            path: path.to_owned(),
            cause: std::io::Error::other(e),
        })?;
        std::fs::write(path, text + "\n").map_err(|cause| CalibrationFileError::Write {
            path: path.to_owned(),
            cause,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Calibration {
        Calibration {
            observer_gain_per_s: Some(50.0),
            coulomb_nm: vec![0.4, 0.3],
            viscous_nms_per_rad: vec![0.5, 0.2],
            offset_nm: vec![0.01, -0.02],
            correlation_secs: vec![0.02, 0.03],
            found: true,
            ..Calibration::none(vec!["a".into(), "b".into()], vec![0.05, 0.07])
        }
    }

    #[test]
    fn a_calibration_survives_the_file() {
        let file = CalibrationFile::new(&sample(), "arm.urdf", vec!["base".into()]);
        let text = serde_json::to_string(&file).unwrap();
        let back = CalibrationFile::parse(&text, Path::new("x.calib.json")).unwrap();
        assert_eq!(back.calibration(Path::new("x")).unwrap(), sample());
    }

    #[test]
    fn bad_fields_are_named() {
        let mut file = CalibrationFile::new(&sample(), "arm.urdf", Vec::new());
        file.viscous_nms_per_rad.push(1.0);
        let err = file.calibration(Path::new("c.json")).unwrap_err().to_string();
        assert!(
            err.contains("c.json") && err.contains("viscous_nms_per_rad") && err.contains("3 values"),
            "{err}"
        );
        let mut file = CalibrationFile::new(&sample(), "arm.urdf", Vec::new());
        file.sigma_nm[1] = 0.0;
        let err = file.calibration(Path::new("c.json")).unwrap_err().to_string();
        assert!(err.contains("sigma_nm") && err.contains("> 0"), "{err}");
        let mut file = CalibrationFile::new(&sample(), "arm.urdf", Vec::new());
        file.observer_gain_per_s = Some(-3.0);
        let err = file.calibration(Path::new("c.json")).unwrap_err().to_string();
        assert!(err.contains("observer_gain_per_s"), "{err}");
        let err = CalibrationFile::parse("{\"format\": 1}", Path::new("c.json"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("not a calibration file"), "{err}");
    }
}
