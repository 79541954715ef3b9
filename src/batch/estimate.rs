//! Every frame of a session estimated in the background, alone or over
//! time, on a [`Latest`] thread: a new job (new settings, another
//! session) replaces the one under way.

use std::sync::Arc;
use std::time::Instant;

use rayon::prelude::*;

use super::pairs::{PairSeen, PairsOver, SingleSeen, session_pairs_timed};
use super::{FrameEstimate, Latest, Serving, SessionData};
use crate::core::config::estimator::EstimatorConfig;
use crate::core::estimate::estimator::Estimator;
use crate::core::over_time::frame::SequenceFrame;
use crate::core::over_time::sequence::{Temporal, estimate_sequence_while};
use crate::core::robot::model::{LinkId, Robot};

/// Everything the background estimation of a session depends on.
#[derive(Debug, Clone)]
pub struct EstimateJob {
    /// Supersedes every smaller one.
    pub generation: u64,
    /// The robot.
    pub robot: Arc<Robot>,
    /// The session.
    pub session: Arc<SessionData>,
    /// The estimator's configuration (its temporal settings for frames
    /// filtered or smoothed).
    pub config: EstimatorConfig,
    /// Candidate links.
    pub links: Vec<LinkId>,
    /// The frame to start from (the one on screen); the rest follow in
    /// order, wrapping around (frames estimated together go in order).
    pub first: usize,
    /// Each frame alone, or together (filtered, smoothed).
    pub over_time: Temporal,
    /// A torque bias per frame to take off (`bias[frame][joint]`, N·m).
    pub bias: Option<Arc<Vec<Vec<f64>>>>,
}

impl EstimateJob {
    /// Frame `index`'s torques, less the bias when there is one.
    fn tau(&self, index: usize) -> Option<Vec<f64>> {
        let frame = self.session.frames.get(index)?;
        Some(match self.bias.as_ref().and_then(|b| b.get(index)) {
            Some(bias) => frame.tau.iter().zip(bias).map(|(t, b)| t - b).collect(),
            None => frame.tau.clone(),
        })
    }
}

/// One frame estimated in the background.
#[derive(Debug, Clone)]
pub struct Estimated {
    /// The job's generation.
    pub generation: u64,
    /// Kept-frame index, or [`EVERY_FRAME`] when the job could not start.
    pub frame: usize,
    /// The estimate, or why there is none.
    pub estimate: Result<FrameEstimate, String>,
}

/// [`Estimated::frame`] of a job that failed before any frame (its
/// estimator could not be made): every frame failed with it.
pub const EVERY_FRAME: usize = usize::MAX;

/// [`Estimated::frame`] of the message that ends a session's pass over
/// the second contacts (with two contacts looked for over time): every
/// frame with an account has been sent again with it. Sent after the
/// frames, whatever the pass found (its `estimate` says so in words).
pub const SECOND_CONTACTS_DONE: usize = usize::MAX - 1;

/// Frames estimated together (in parallel) between looks for a newer job.
const BATCH_FRAMES: usize = 32;

/// Estimates every frame of a session on a thread of its own; a new job
/// replaces the one under way (between batches of frames).
pub struct SessionWorker {
    thread: Latest<EstimateJob, Estimated>,
}

impl SessionWorker {
    /// Starts the thread; `wake` is called when results are waiting.
    pub fn spawn(wake: impl Fn() + Send + 'static) -> Self {
        Self {
            thread: Latest::spawn(wake, |job, serving| serve(&job, serving)),
        }
    }

    /// Starts a job (superseding the one under way).
    pub fn start(&self, job: EstimateJob) {
        self.thread.request(job);
    }

    /// Everything estimated since the last call.
    pub fn drain(&self) -> impl Iterator<Item = Estimated> + '_ {
        self.thread.results()
    }
}

/// Serves one job: every frame, alone in parallel batches from the one on
/// screen, or together in order; a newer job stops it.
fn serve(job: &EstimateJob, serving: &Serving<'_, EstimateJob, Estimated>) {
    let made = crate::io::guard::isolated(|| {
        job.config
            .estimator(&job.robot, job.links.clone(), job.over_time)
            .map_err(|e| e.to_string())
    })
    .and_then(|r| r);
    let estimator = match made {
        Ok(e) => e,
        Err(e) => {
            serving.send(Estimated {
                generation: job.generation,
                frame: EVERY_FRAME,
                estimate: Err(e),
            });
            return;
        }
    };
    if job.over_time != Temporal::None {
        estimate_together(job, &estimator, serving);
        return;
    }
    let frames = &job.session.frames;
    let estimate_frame = |index: usize| -> Estimated {
        // A panic on one frame fails that frame, not the thread.
        let estimate = crate::io::guard::isolated(|| {
            frames.get(index).map_or_else(
                || Err(format!("no frame {index}")),
                |frame| {
                    let positions = job.robot.joint_positions(&frame.q, &[]).map_err(|e| e.to_string())?;
                    let tau = job.tau(index).unwrap_or_default();
                    let t0 = Instant::now();
                    let update = estimator
                        .update(&job.robot, &positions, &tau)
                        .map_err(|e| e.to_string())?;
                    let ms = t0.elapsed().as_secs_f64() * 1e3;
                    Ok(FrameEstimate::of_frame(
                        &job.robot,
                        &estimator.surface,
                        &update,
                        ms,
                        &frame.truth,
                    ))
                },
            )
        })
        .map_err(|message| {
            log::error!("estimating session frame {index} failed: {message}");
            format!("the estimator failed: {message}")
        })
        .and_then(|r| r);
        Estimated {
            generation: job.generation,
            frame: index,
            estimate,
        }
    };
    // Frames in order from the one on screen, a batch at a time shared
    // among threads; a newer job is looked for between batches.
    let order: Vec<usize> = (0..frames.len())
        .map(|step| (job.first + step) % frames.len())
        .collect();
    for batch in order.chunks(BATCH_FRAMES) {
        if serving.should_stop() {
            return;
        }
        let done: Vec<Estimated> = batch.par_iter().map(|&i| estimate_frame(i)).collect();
        for estimated in done {
            if !serving.send(estimated) {
                return;
            }
        }
        serving.wake_now_and_then();
    }
}

/// A frame's estimate as sent and its single contact, kept for the pass
/// over the second contacts (`None`: not estimated).
type Kept = Option<(FrameEstimate, Option<SingleSeen>)>;

/// The session's second contacts after its frames (`kept`, each frame's
/// estimate as sent and its single contact): the pairs searched in order,
/// the chain smoothed (filtered where the frames are), and every frame
/// with a pair account sent again carrying it; what came of it, in words.
/// A failed search leaves the frames as they were (logged); a newer job
/// stops it.
fn second_contacts(
    job: &EstimateJob,
    estimator: &Estimator,
    sequence: &[SequenceFrame<'_>],
    kept: &[Kept],
    serving: &Serving<'_, EstimateJob, Estimated>,
) -> String {
    let singles: Vec<Option<SingleSeen>> = kept.iter().map(|k| k.and_then(|(_, single)| single)).collect();
    let over = PairsOver::of(job.over_time, job.config.second_contact_chain());
    let pairs = match session_pairs_timed(
        estimator,
        &job.robot,
        sequence,
        &singles,
        &job.config.pair,
        over,
        || !serving.should_stop(),
    ) {
        Ok(Some((pairs, _))) => pairs,
        Ok(None) => return "stopped for a newer estimation".to_owned(),
        Err((frame, e)) => {
            log::error!("the second contact at session frame {frame}: {e}");
            return format!("the second contact at frame {frame} could not be searched: {e}");
        }
    };
    let mut called = 0;
    for (frame, (pair, k)) in pairs.iter().zip(kept).enumerate() {
        let (Some(pair), Some((estimate, _))) = (pair, k) else {
            continue;
        };
        let second = PairSeen::of(pair);
        called += usize::from(second.called);
        let estimate = FrameEstimate {
            second: Some(second),
            ..*estimate
        };
        let sent = serving.send(Estimated {
            generation: job.generation,
            frame,
            estimate: Ok(estimate),
        });
        if !sent {
            return "stopped for a newer estimation".to_owned();
        }
    }
    format!("two contacts in {called} frames")
}

/// Estimates `job`'s frames together (filtered or smoothed), in order,
/// sending each as it is done; a newer job stops it between frames. A
/// failure (or a panic) fails every frame not yet sent.
fn estimate_together(job: &EstimateJob, estimator: &Estimator, serving: &Serving<'_, EstimateJob, Estimated>) {
    let frames = &job.session.frames;
    let sent = std::cell::RefCell::new(vec![false; frames.len()]);
    // With two contacts: each frame's estimate as sent and its single
    // contact, for the pass over the second contacts once all are in.
    let two = job.config.contacts_at_once >= 2;
    let kept: std::cell::RefCell<Vec<Kept>> =
        std::cell::RefCell::new(if two { vec![None; frames.len()] } else { Vec::new() });
    let result = crate::io::guard::isolated(|| -> Result<String, String> {
        let positions = frames
            .iter()
            .map(|f| job.robot.joint_positions(&f.q, &[]).map_err(|e| e.to_string()))
            .collect::<Result<Vec<_>, _>>()?;
        let taus: Vec<Vec<f64>> = (0..frames.len()).map(|i| job.tau(i).unwrap_or_default()).collect();
        let sequence: Vec<SequenceFrame> = frames
            .iter()
            .zip(&positions)
            .zip(&taus)
            .map(|((f, p), tau)| SequenceFrame {
                t_secs: f.t,
                joint_positions: p,
                tau,
            })
            .collect();
        let model = job
            .config
            .temporal_model(&estimator.surface, estimator.uses_patches())
            .map_err(|e| e.to_string())?;
        estimate_sequence_while(
            estimator,
            &job.robot,
            (Some(&model), job.over_time),
            &sequence,
            || !serving.should_stop(),
            |frame, update, ms| {
                let estimate = match frames.get(frame) {
                    Some(f) => FrameEstimate::of_frame(&job.robot, &estimator.surface, &update, ms, &f.truth),
                    None => FrameEstimate::of(&update, ms),
                };
                if let Some(slot) = kept.borrow_mut().get_mut(frame) {
                    *slot = Some((estimate, SingleSeen::of(&update)));
                }
                serving.send(Estimated {
                    generation: job.generation,
                    frame,
                    estimate: Ok(estimate),
                });
                if let Some(s) = sent.borrow_mut().get_mut(frame) {
                    *s = true;
                }
                serving.wake_now_and_then();
            },
            // A frame that cannot be estimated is counted and left out;
            // the frames around it carry the contact over.
            |frame, error| {
                log::error!("estimating session frame {frame} failed: {error}");
                serving.send(Estimated {
                    generation: job.generation,
                    frame,
                    estimate: Err(error.to_string()),
                });
                if let Some(s) = sent.borrow_mut().get_mut(frame) {
                    *s = true;
                }
                true
            },
        )
        .map_err(|e| e.to_string())?;
        Ok(if two && !serving.should_stop() {
            second_contacts(job, estimator, &sequence, &kept.borrow(), serving)
        } else {
            String::new()
        })
    });
    if serving.should_stop() {
        return;
    }
    let failure = match result {
        Ok(Ok(said)) => {
            if two {
                second_contacts_done(job, serving, said);
            }
            return;
        }
        Ok(Err(e)) => e,
        Err(panic) => format!("the estimator failed: {panic}"),
    };
    log::error!("estimating the session over time failed: {failure}");
    for (frame, _) in sent.into_inner().iter().enumerate().filter(|(_, s)| !**s) {
        let failed = Estimated {
            generation: job.generation,
            frame,
            estimate: Err(failure.clone()),
        };
        if !serving.send(failed) {
            return;
        }
    }
    if two {
        second_contacts_done(job, serving, format!("no second contacts: {failure}"));
    }
}

/// Says that the pass over the second contacts is over ([`SECOND_CONTACTS_DONE`]).
fn second_contacts_done(job: &EstimateJob, serving: &Serving<'_, EstimateJob, Estimated>, said: String) {
    serving.send(Estimated {
        generation: job.generation,
        frame: SECOND_CONTACTS_DONE,
        estimate: Err(said),
    });
    serving.wake_now_and_then();
}
