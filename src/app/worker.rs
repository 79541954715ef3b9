//! The estimator off the UI thread, on the one worker mechanism
//! ([`Latest`]): requests go in, the newest one is worked on (older ones
//! waiting are dropped), results come back. And one-shot jobs
//! ([`Background`]: opening a scene or a robot).

use std::sync::Arc;
use std::time::Instant;

pub use crate::batch::Background;
use crate::batch::{Latest, Serving};
use crate::core::config::estimator::EstimatorConfig;
use crate::core::estimate::estimator::{Estimator, Update};
use crate::core::estimate::pair::{PairEstimate, PairStart};
use crate::core::estimate::settings::EstimatorSettings;
use crate::core::over_time::sequence::Temporal;
use crate::core::robot::model::{LinkId, Robot};
use crate::core::surface::sampling::{Surface, SurfaceRequest};
use crate::render::scene::{VertexSamples, nearest_samples};

/// The sampled surface kept between requests: which robot, links and
/// resolution it was made for.
struct Cached {
    /// Held (not only its address) so that a later robot can never be
    /// mistaken for this one by landing at the same address.
    robot: Arc<Robot>,
    links: Vec<LinkId>,
    points: usize,
    seed: u64,
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
    /// The estimator's configuration (a frame alone).
    pub config: EstimatorConfig,
    /// Candidate links.
    pub links: Vec<LinkId>,
}

impl Request {
    /// The surface the request samples.
    fn surface(&self) -> SurfaceRequest {
        self.config.surface_request(self.links.clone())
    }

    /// The estimator's settings for a frame alone (the model keeps its
    /// configuration valid; an invalid one estimates nothing).
    fn settings(&self) -> Result<EstimatorSettings, String> {
        self.config
            .settings(self.robot.sensed().len(), Temporal::None)
            .map_err(|e| e.to_string())
    }
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
    /// The two-contact account, where the configuration looks for two
    /// contacts at once (`None` otherwise, or where no second place is
    /// found), or why it failed.
    pub pair: Option<Result<PairEstimate, String>>,
}

/// Handle to the worker thread (a [`Latest`] thread: the newest request
/// wins).
pub struct Worker {
    thread: Latest<Request, Outcome>,
}

impl Worker {
    /// Starts the thread; `wake` is called after each result (to repaint).
    pub fn spawn(wake: impl Fn() + Send + 'static) -> Self {
        let mut cache: Option<Cached> = None;
        Self::spawn_with(wake, move |request| serve(&mut cache, request))
    }

    /// Starts a thread that answers each request with `serve`, supervised:
    /// a panic inside `serve` is caught, logged on standard error and
    /// answered as an error outcome naming it, and the thread goes on with
    /// the next request (`serve` keeps no state a panic could leave half
    /// made: see `serve`).
    pub fn spawn_with<S>(wake: impl Fn() + Send + 'static, serve: S) -> Self
    where
        S: FnMut(&Request) -> Outcome + Send + 'static,
    {
        let mut serve = serve;
        let thread = Latest::spawn(
            wake,
            move |request: Request, serving: &Serving<'_, Request, Outcome>| {
                let outcome = match crate::io::guard::isolated(|| serve(&request)) {
                    Ok(outcome) => outcome,
                    Err(message) => {
                        log::error!("the estimator failed and was restarted: {message}");
                        failed(&request, format!("the estimator failed and was restarted: {message}"))
                    }
                };
                serving.send(outcome);
            },
        );
        Self { thread }
    }

    /// Queues a request (it supersedes any still waiting).
    pub fn request(&self, request: Request) {
        self.thread.request(request);
    }

    /// The newest outcome that has arrived, if any.
    #[must_use]
    pub fn latest(&self) -> Option<Outcome> {
        self.thread.results().last()
    }
}

/// An outcome that reports `message` instead of an estimate.
fn failed(request: &Request, message: String) -> Outcome {
    Outcome {
        generation: request.generation,
        robot: request.robot.clone(),
        estimator: Arc::new(Estimator {
            surface: Surface::default(),
            links: Vec::new(),
            hierarchy: None,
            settings: request
                .settings()
                .unwrap_or_else(|_| EstimatorSettings::exact(vec![0.0; request.robot.sensed().len()])),
        }),
        nearest: Arc::new(Vec::new()),
        update: Err(message),
        update_ms: 0.0,
        pair: None,
    }
}

/// The worker's answer to one request, on the caller's thread, with no
/// surface kept for the next.
#[cfg(test)]
pub(crate) fn answer(request: &Request) -> Outcome {
    serve(&mut None, request)
}

/// Answers one request, reusing the sampled surface in `cache` when the
/// robot, links, resolution and phases are those it was made for. A
/// panic leaves `cache` empty (it is rebuilt by the next request).
fn serve(cache: &mut Option<Cached>, request: &Request) -> Outcome {
    let settings = match request.settings() {
        Ok(settings) => settings,
        Err(e) => return failed(request, e),
    };
    let surface = request.surface();
    let phase_sizes = request.config.phase_sizes();
    let reuse = cache.as_ref().is_some_and(|c| {
        Arc::ptr_eq(&c.robot, &request.robot)
            && c.links == surface.links
            && c.points == surface.total_points
            && c.seed == surface.seed
            && c.phase_sizes == phase_sizes
    });
    if !reuse {
        // Dropped first: a panic below leaves no half-made cache behind.
        *cache = None;
        match Estimator::new(&request.robot, &surface, settings.clone(), phase_sizes) {
            Ok(estimator) => {
                let nearest = nearest_samples(&request.robot, &estimator.surface);
                *cache = Some(Cached {
                    robot: request.robot.clone(),
                    links: surface.links.clone(),
                    points: surface.total_points,
                    seed: surface.seed,
                    phase_sizes,
                    estimator: Arc::new(estimator),
                    nearest: Arc::new(nearest),
                });
            }
            Err(e) => return failed(request, e.to_string()),
        }
    }
    let Some(Cached { estimator, nearest, .. }) = cache.as_mut() else {
        return failed(request, "no surface".to_owned());
    };
    if estimator.settings != settings {
        let mut changed = (**estimator).clone();
        changed.settings = settings;
        *estimator = Arc::new(changed);
    }
    let estimator = estimator.clone();
    let nearest = nearest.clone();
    // Taken out while it works: a panic inside leaves the cache empty.
    let kept = cache.take();
    let t0 = Instant::now();
    let update = estimator
        .update(&request.robot, &request.joint_positions, &request.tau)
        .map_err(|e| e.to_string());
    let update_ms = t0.elapsed().as_secs_f64() * 1e3;
    // A frame on its own: the pair is searched from the coarse grid (its
    // single contact can lie on neither push), whatever the fit test says,
    // so that the panel always has the evidence for two.
    let pair = (request.config.contacts_at_once >= 2 && update.is_ok())
        .then(|| {
            estimator
                .pair_at(
                    &request.robot,
                    &request.joint_positions,
                    &request.tau,
                    &request.config.pair,
                    &[PairStart::Unknown],
                )
                .map_err(|e| e.to_string())
                .transpose()
        })
        .flatten();
    *cache = kept;
    Outcome {
        generation: request.generation,
        robot: request.robot.clone(),
        estimator,
        nearest,
        update,
        update_ms,
        pair,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::config::estimator::Sigma;

    fn request(generation: u64) -> Request {
        Request {
            generation,
            robot: Arc::new(crate::core::robot::builtin::simple6().unwrap_or_else(|e| panic!("{e}"))),
            joint_positions: vec![0.0; 6],
            tau: vec![0.0; 6],
            config: EstimatorConfig {
                sigma: Sigma::All(0.1),
                force_range_newtons: (1.0, 2.0),
                surface_points: 16,
                ..EstimatorConfig::default()
            },
            links: vec![1],
        }
    }

    /// A panic inside the worker is answered as an error naming it, and
    /// the next request is served.
    #[test]
    fn a_panicking_estimate_is_reported_and_the_worker_goes_on() {
        let worker = Worker::spawn_with(
            || {},
            |r: &Request| {
                assert!(r.generation != 1, "injected failure");
                failed(r, "fine".to_owned())
            },
        );
        let wait = || {
            for _ in 0..500 {
                if let Some(o) = worker.latest() {
                    return o;
                }
                std::thread::sleep(std::time::Duration::from_millis(10));
            }
            panic!("no outcome");
        };
        worker.request(request(1));
        let first = wait();
        let message = first.update.err().unwrap_or_default();
        assert!(
            message.contains("restarted") && message.contains("injected failure"),
            "{message}"
        );
        worker.request(request(2));
        let second = wait();
        assert_eq!(second.generation, 2);
        assert_eq!(second.update.err().as_deref(), Some("fine"));
    }
}
