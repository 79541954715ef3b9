//! The estimator off the UI thread: requests go in, the newest one is
//! worked on (older ones waiting are dropped), results come back.

use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::time::Instant;

use crate::core::estimator::EstimatorSettings;
use crate::core::pipeline::{Estimator, Update};
use crate::core::robot::{LinkId, Robot};
use crate::core::surface::{Surface, SurfaceRequest};
use crate::render::scene::{VertexSamples, nearest_samples};

/// The sampled surface kept between requests: which robot, links and
/// resolution it was made for.
struct Cached {
    /// Held (not only its address) so that a later robot can never be
    /// mistaken for this one by landing at the same address.
    robot: Arc<Robot>,
    links: Vec<LinkId>,
    points: usize,
    phase_sizes: Option<[usize; 2]>,
    estimator: Arc<Estimator>,
    nearest: Arc<Vec<Vec<VertexSamples>>>,
}

/// What to estimate.
#[derive(Debug, Clone)]
pub struct Request {
    /// Increases with every request; results carry it back.
    pub generation: u64,
    /// The robot.
    pub robot: Arc<Robot>,
    /// Every joint's position.
    pub joint_positions: Vec<f64>,
    /// Measured torques.
    pub tau: Vec<f64>,
    /// Candidate links and surface resolution.
    pub surface: SurfaceRequest,
    /// Likelihood settings.
    pub settings: EstimatorSettings,
    /// Sizes of phases A and B when phases are on (the hierarchy is built
    /// with the surface).
    pub phase_sizes: Option<[usize; 2]>,
}

/// A finished estimate.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The request's generation.
    pub generation: u64,
    /// The robot it was computed for: an outcome is shown only while this
    /// is the model's robot.
    pub robot: Arc<Robot>,
    /// The estimator it used (surface included).
    pub estimator: Arc<Estimator>,
    /// Per link and mesh vertex, the nearest surface sample (for the heatmap).
    pub nearest: Arc<Vec<Vec<VertexSamples>>>,
    /// The posterior and its summary, or what went wrong.
    pub update: Result<Update, String>,
    /// Time of the update, ms (surface sampling excluded).
    pub update_ms: f64,
}

/// Handle to the worker thread.
pub struct Worker {
    requests: Sender<Request>,
    outcomes: Receiver<Outcome>,
}

impl Worker {
    /// Starts the thread; `wake` is called after each result (to repaint).
    pub fn spawn(wake: impl Fn() + Send + 'static) -> Self {
        let (requests, inbox) = channel::<Request>();
        let (outbox, outcomes) = channel::<Outcome>();
        std::thread::spawn(move || {
            let mut cache: Option<Cached> = None;
            while let Ok(mut request) = inbox.recv() {
                // Only the newest request matters.
                while let Ok(newer) = inbox.try_recv() {
                    request = newer;
                }
                let reuse = cache.as_ref().is_some_and(|c| {
                    Arc::ptr_eq(&c.robot, &request.robot)
                        && c.links == request.surface.links
                        && c.points == request.surface.total_points
                        && c.phase_sizes == request.phase_sizes
                });
                if !reuse {
                    match Estimator::new(
                        &request.robot,
                        &request.surface,
                        request.settings.clone(),
                        request.phase_sizes,
                    ) {
                        Ok(estimator) => {
                            let nearest = nearest_samples(&request.robot, &estimator.surface);
                            cache = Some(Cached {
                                robot: request.robot.clone(),
                                links: request.surface.links.clone(),
                                points: request.surface.total_points,
                                phase_sizes: request.phase_sizes,
                                estimator: Arc::new(estimator),
                                nearest: Arc::new(nearest),
                            });
                        }
                        Err(e) => {
                            let empty = Estimator {
                                surface: Surface::default(),
                                links: Vec::new(),
                                hierarchy: None,
                                settings: request.settings.clone(),
                            };
                            let _ = outbox.send(Outcome {
                                generation: request.generation,
                                robot: request.robot.clone(),
                                estimator: Arc::new(empty),
                                nearest: Arc::new(Vec::new()),
                                update: Err(e.to_string()),
                                update_ms: 0.0,
                            });
                            wake();
                            continue;
                        }
                    }
                }
                let Some(Cached { estimator, nearest, .. }) = cache.as_mut() else {
                    continue;
                };
                if estimator.settings != request.settings {
                    let mut changed = (**estimator).clone();
                    changed.settings = request.settings.clone();
                    *estimator = Arc::new(changed);
                }
                let t0 = Instant::now();
                let update = estimator
                    .update(&request.robot, &request.joint_positions, &request.tau)
                    .map_err(|e| e.to_string());
                let update_ms = t0.elapsed().as_secs_f64() * 1e3;
                if outbox
                    .send(Outcome {
                        generation: request.generation,
                        robot: request.robot.clone(),
                        estimator: estimator.clone(),
                        nearest: nearest.clone(),
                        update,
                        update_ms,
                    })
                    .is_err()
                {
                    break;
                }
                wake();
            }
        });
        Self { requests, outcomes }
    }

    /// Queues a request (it supersedes any still waiting).
    pub fn request(&self, request: Request) {
        let _ = self.requests.send(request);
    }

    /// The newest outcome that has arrived, if any.
    #[must_use]
    pub fn latest(&self) -> Option<Outcome> {
        self.outcomes.try_iter().last()
    }
}
