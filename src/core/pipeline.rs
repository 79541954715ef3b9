//! The estimator as a pipeline: the surface and the phase hierarchy are
//! built once (they live in link frames), then each measurement is an
//! update at its own configuration.

use crate::core::contact::{PosedSurface, UnitTorqueSource as _};
use crate::core::estimator::{EstimateError, EstimatorSettings, Mode, Posterior, estimate};
use crate::core::kinematics::RobotPose;
use crate::core::phases::PhaseHierarchy;
use crate::core::refine::{Measurement, refine};
use crate::core::robot::{LinkId, Robot};
use crate::core::special::chi_square_survival;
use crate::core::summary::{NO_CONTACT_P, Refinement, Summary, summarize_refined};
use crate::core::surface::{Surface, SurfaceError, SurfaceRequest};
use crate::core::torque::TorqueModel;

/// Everything fixed across updates.
#[derive(Debug, Clone)]
pub struct Estimator {
    /// Candidate surface points.
    pub surface: Surface,
    /// Candidate links.
    pub links: Vec<LinkId>,
    /// Phases A/B/C, when used.
    pub hierarchy: Option<PhaseHierarchy>,
    /// Noise model, force range, mode.
    pub settings: EstimatorSettings,
}

/// One measurement's result.
#[derive(Debug, Clone)]
pub struct Update {
    /// The robot at the measurement's configuration.
    pub pose: RobotPose,
    /// The posterior over the surface points.
    pub posterior: Posterior,
    /// What it says.
    pub summary: Summary,
}

impl Estimator {
    /// Samples the surface and, with `phase_sizes`, builds the phase
    /// hierarchy (seeded by the surface seed).
    pub fn new(
        robot: &Robot,
        request: &SurfaceRequest,
        settings: EstimatorSettings,
        phase_sizes: Option<[usize; 2]>,
    ) -> Result<Self, SurfaceError> {
        let surface = Surface::sample(robot, request)?;
        // The evidence's erfc fit is built on first use: here, not in the
        // first update (a few milliseconds that would be that frame's).
        let _ = crate::core::fastmath::ErfTable::get();
        let hierarchy = phase_sizes.map(|sizes| PhaseHierarchy::new(&surface, sizes, request.seed));
        Ok(Self {
            surface,
            links: request.links.clone(),
            hierarchy,
            settings,
        })
    }

    /// The posterior for torques `tau` measured at `joint_positions`
    /// (every joint's, see [`Robot::joint_positions`]).
    pub fn update(&self, robot: &Robot, joint_positions: &[f64], tau: &[f64]) -> Result<Update, EstimateError> {
        let pose = RobotPose::new(robot, joint_positions);
        let torque_model = TorqueModel::new(robot, &pose, &self.links);
        let posed = PosedSurface {
            torque_model: &torque_model,
            surface: &self.surface,
        };
        let posterior = estimate(&posed, tau, &self.settings, self.hierarchy.as_ref())?;
        // Torques within noise of zero: there is no contact to place, so
        // none is refined (the summary reports the most probable sample).
        let no_contact = chi_square_survival(posterior.no_contact_chi2, posed.joints()) > NO_CONTACT_P;
        let refined = (self.settings.patches && self.settings.mode == Mode::Exact && !no_contact)
            .then(|| {
                let weights: Vec<f64> = self.settings.sigma.iter().map(|s| 1.0 / (s * s)).collect();
                let measurement = Measurement {
                    tau,
                    weights: &weights,
                    force_range_newtons: (self.settings.force_min_newtons, self.settings.force_max_newtons),
                };
                refine(&torque_model, &self.surface, &posterior, &measurement)
            })
            .flatten();
        let summary = summarize_refined(
            &posterior,
            &self.surface,
            &pose,
            posed.joints(),
            refined.as_ref().map(|contact| Refinement {
                contact,
                sensing_joints: torque_model.twists(contact.link).len(),
            }),
        );
        Ok(Update {
            pose,
            posterior,
            summary,
        })
    }
}
