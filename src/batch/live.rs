//! A live session's frames filtered as they arrive, on a thread of their
//! own: each frame with the frames before it (what `estimate --live`
//! writes, a second contact too when two are looked for), for the app's
//! timeline while a stream is listened to.

use std::collections::VecDeque;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, TryIter, channel};
use std::time::Instant;

use super::pairs::{LivePairs, PairSeen};
use super::{Estimated, FrameEstimate};
use crate::core::config::estimator::EstimatorConfig;
use crate::core::estimate::estimator::Estimator;
use crate::core::over_time::sequence::{StreamFilter, Temporal};
use crate::core::over_time::temporal::TemporalModel;
use crate::core::robot::model::{LinkId, Robot};
use crate::io::session::Frame;

/// What filtering a live session depends on; a new one starts over from
/// its first frame.
#[derive(Debug, Clone)]
pub struct LiveJob {
    /// Results carry it back; it supersedes every smaller one.
    pub generation: u64,
    /// The robot.
    pub robot: Arc<Robot>,
    /// The frames received so far (more follow with [`LiveFilterWorker::append`]).
    pub frames: Vec<Frame>,
    /// The estimator's configuration (its temporal settings included).
    pub config: EstimatorConfig,
    /// Candidate links.
    pub links: Vec<LinkId>,
}

/// What the thread is told.
enum Message {
    /// Start over (new settings, a new sender).
    Start(Box<LiveJob>),
    /// Frames that arrived after the job's, in order.
    Append(Vec<Frame>),
}

/// Handle to the thread that filters a live session: frames are estimated
/// in order, one at a time, each result sent back as soon as it is done;
/// a new job replaces the one under way between two frames.
pub struct LiveFilterWorker {
    messages: Sender<Message>,
    results: Receiver<Estimated>,
}

impl LiveFilterWorker {
    /// Starts the thread; `wake` is called after each frame estimated.
    pub fn spawn(wake: impl Fn() + Send + 'static) -> Self {
        let (messages, inbox) = channel::<Message>();
        let (outbox, results) = channel::<Estimated>();
        std::thread::spawn(move || serve(&inbox, &outbox, &wake));
        Self { messages, results }
    }

    /// Starts filtering `job`'s frames from the first (superseding the job
    /// under way).
    pub fn start(&self, job: LiveJob) {
        // The thread ends only when this handle is dropped.
        let _ = self.messages.send(Message::Start(Box::new(job)));
    }

    /// Frames that arrived after those already given, in order.
    pub fn append(&self, frames: Vec<Frame>) {
        let _ = self.messages.send(Message::Append(frames));
    }

    /// Everything estimated since the last call.
    #[must_use]
    pub fn drain(&self) -> TryIter<'_, Estimated> {
        self.results.try_iter()
    }
}

/// The job under way: its estimator and model, the filter's state and
/// the frames not yet estimated.
struct Running {
    job: LiveJob,
    estimator: Estimator,
    model: TemporalModel,
    filter: StreamFilter,
    /// With two contacts looked for: the second followed frame by frame.
    pairs: Option<LivePairs>,
    queue: VecDeque<Frame>,
    next: usize,
}

/// The thread: takes every message waiting, then estimates the next frame
/// queued (or waits for a message when none is).
fn serve(inbox: &Receiver<Message>, outbox: &Sender<Estimated>, wake: &dyn Fn()) {
    let mut running: Option<Running> = None;
    loop {
        let idle = running.as_ref().is_none_or(|r| r.queue.is_empty());
        let first = if idle {
            match inbox.recv() {
                Ok(message) => Some(message),
                Err(_) => return,
            }
        } else {
            None
        };
        for message in first.into_iter().chain(inbox.try_iter()) {
            match message {
                Message::Start(job) => {
                    running = match begin(*job) {
                        Ok(r) => Some(r),
                        Err((generation, e)) => {
                            let failed = Estimated {
                                generation,
                                frame: super::EVERY_FRAME,
                                estimate: Err(e),
                            };
                            if outbox.send(failed).is_err() {
                                return;
                            }
                            wake();
                            None
                        }
                    };
                }
                Message::Append(frames) => {
                    if let Some(r) = running.as_mut() {
                        r.queue.extend(frames);
                    }
                }
            }
        }
        let Some(r) = running.as_mut() else {
            continue;
        };
        let Some(frame) = r.queue.pop_front() else {
            continue;
        };
        let estimated = step(r, &frame);
        if outbox.send(estimated).is_err() {
            return;
        }
        wake();
    }
}

/// The estimator and temporal model of `job` (or its generation and why
/// they cannot be made).
fn begin(mut job: LiveJob) -> Result<Running, (u64, String)> {
    let generation = job.generation;
    let made = crate::io::guard::isolated(|| -> Result<(Estimator, TemporalModel), String> {
        let estimator = job
            .config
            .estimator(&job.robot, job.links.clone(), Temporal::Filter)
            .map_err(|e| e.to_string())?;
        let model = job
            .config
            .temporal_model(&estimator.surface, estimator.uses_patches())
            .map_err(|e| e.to_string())?;
        Ok((estimator, model))
    });
    let (estimator, model) = made.and_then(|r| r).map_err(|e| (generation, e))?;
    // The frames move to the queue: a long session is not held twice.
    let queue = VecDeque::from(std::mem::take(&mut job.frames));
    let pairs =
        (job.config.contacts_at_once >= 2).then(|| LivePairs::new(job.config.pair, job.config.second_contact_chain()));
    Ok(Running {
        job,
        estimator,
        model,
        filter: StreamFilter::default(),
        pairs,
        queue,
        next: 0,
    })
}

/// The next frame through the filter. A frame that fails (or panics) is
/// reported and left out; the frames after it go on from the ones before.
fn step(r: &mut Running, frame: &Frame) -> Estimated {
    let index = r.next;
    r.next += 1;
    let estimate = crate::io::guard::isolated(|| -> Result<FrameEstimate, String> {
        let positions = r.job.robot.joint_positions(&frame.q, &[]).map_err(|e| e.to_string())?;
        let t0 = Instant::now();
        let update = r
            .filter
            .update(
                &r.estimator,
                &r.model,
                &r.job.robot,
                (index, frame.t),
                &positions,
                &frame.tau,
            )
            .map_err(|e| e.to_string())?;
        // A second contact as `estimate --live --contacts 2` follows it.
        let second = match r.pairs.as_mut() {
            Some(pairs) => pairs
                .push(&r.estimator, &r.job.robot, (frame, &positions), &update)
                .map_err(|e| format!("the second contact: {e}"))?
                .as_ref()
                .map(PairSeen::of),
            None => None,
        };
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        Ok(FrameEstimate {
            second,
            ..FrameEstimate::of_frame(&r.job.robot, &r.estimator.surface, &update, ms, &frame.truth)
        })
    })
    .map_err(|message| format!("the estimator failed: {message}"))
    .and_then(|e| e);
    Estimated {
        generation: r.job.generation,
        frame: index,
        estimate,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::estimate::estimator::Update;
    use crate::core::eval::synth::{SynthSettings, synthesize};
    use crate::core::over_time::frame::SequenceFrame;
    use crate::core::over_time::sequence::{Temporal, estimate_sequence_while};
    use crate::io::session::Truth;

    /// The generated LWR and its links named `links`.
    fn lwr(links: &[&str]) -> (Arc<Robot>, Vec<LinkId>) {
        let robot = Arc::new(crate::core::robot::builtin::lwr4plus_generated().unwrap_or_else(|e| panic!("{e}")));
        let links = links.iter().filter_map(|l| robot.link_id(l).ok()).collect();
        (robot, links)
    }

    /// A synthesized session's frames (seed `seed`), as a stream sends them.
    fn frames_of(robot: &Robot, links: &[LinkId], settings: &SynthSettings, seed: u64) -> Vec<Frame> {
        synthesize(robot, links, settings, seed)
            .unwrap_or_else(|e| panic!("{e}"))
            .into_iter()
            .map(|f| Frame {
                t: f.t_secs,
                q: f.q,
                tau: f.tau,
                truth: Truth::Unknown,
                truth_all: Vec::new(),
            })
            .collect()
    }

    /// The whole recording filtered at once: `each` gets every frame's
    /// update with the frames as the sequence takes them; the estimator
    /// made for it.
    fn filtered_whole(
        (robot, links): (&Robot, &[LinkId]),
        config: &EstimatorConfig,
        frames: &[Frame],
        mut each: impl FnMut(usize, Update),
        after: impl FnOnce(&Estimator, &[SequenceFrame]),
    ) {
        let estimator = config
            .estimator(robot, links.to_vec(), Temporal::Filter)
            .unwrap_or_else(|e| panic!("{e}"));
        let model = config
            .temporal_model(&estimator.surface, estimator.uses_patches())
            .unwrap_or_else(|e| panic!("{e}"));
        let positions: Vec<Vec<f64>> = frames
            .iter()
            .map(|f| robot.joint_positions(&f.q, &[]).unwrap_or_default())
            .collect();
        let sequence: Vec<SequenceFrame> = frames
            .iter()
            .zip(&positions)
            .map(|(f, p)| SequenceFrame {
                t_secs: f.t,
                joint_positions: p,
                tau: &f.tau,
            })
            .collect();
        estimate_sequence_while(
            &estimator,
            robot,
            (Some(&model), Temporal::Filter),
            &sequence,
            || true,
            |i, update, _| each(i, update),
            |_, _| false,
        )
        .unwrap_or_else(|e| panic!("{e}"));
        after(&estimator, &sequence);
    }

    /// Every frame of generation `generation` that `worker` sends, until
    /// it has sent `frames`.
    fn collect_live(worker: &LiveFilterWorker, generation: u64, frames: usize) -> Vec<FrameEstimate> {
        let mut live: Vec<Option<FrameEstimate>> = vec![None; frames];
        let started = Instant::now();
        while live.iter().any(Option::is_none) {
            assert!(started.elapsed().as_secs() < 120, "the stream was not estimated");
            for done in worker.drain().filter(|d| d.generation == generation) {
                let estimate = done.estimate.unwrap_or_else(|e| panic!("frame {}: {e}", done.frame));
                live[done.frame] = Some(estimate);
            }
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        live.into_iter().flatten().collect()
    }

    /// Frames given in pieces as they "arrive" are estimated as the
    /// filter estimates the whole recording: the same places, forces and
    /// contact probabilities, frame by frame.
    #[test]
    fn a_stream_in_pieces_is_filtered_as_the_whole_recording() {
        let (robot, links) = lwr(&["lwr_5_link", "lwr_6_link"]);
        let settings = SynthSettings {
            duration_secs: 2.0,
            rate_hz: 25.0,
            press_secs: (0.5, 0.8),
            gap_secs: (0.2, 0.3),
            ..SynthSettings::default()
        };
        let frames = frames_of(&robot, &links, &settings, 5);
        assert_eq!(frames.len(), 50);
        let config = EstimatorConfig {
            surface_points: 600,
            ..EstimatorConfig::default()
        };
        let mut whole = Vec::new();
        filtered_whole(
            (&robot, &links),
            &config,
            &frames,
            |_, update| whole.push(FrameEstimate::of(&update, 0.0)),
            |_, _| {},
        );

        // The same frames arriving in pieces, after a first job that a
        // second replaces.
        let worker = LiveFilterWorker::spawn(|| {});
        let job = |generation: u64, frames: &[Frame]| LiveJob {
            generation,
            robot: robot.clone(),
            frames: frames.to_vec(),
            config: config.clone(),
            links: links.clone(),
        };
        worker.start(job(1, &frames[..5]));
        worker.start(job(2, &frames[..12]));
        worker.append(frames[12..30].to_vec());
        worker.append(frames[30..].to_vec());
        let live = collect_live(&worker, 2, frames.len());
        assert_eq!(whole.len(), frames.len());
        let contacts = whole.iter().filter(|e| e.contact_probability > Some(0.5)).count();
        assert!(
            contacts > 5,
            "{contacts} contact frames: the comparison would say little"
        );
        for (i, (w, l)) in whole.iter().zip(&live).enumerate() {
            assert_eq!(l.point_world, w.point_world, "frame {i}");
            assert_eq!(l.force_world, w.force_world, "frame {i}");
            assert_eq!(l.contact_probability, w.contact_probability, "frame {i}");
            assert_eq!(l.verdict, w.verdict, "frame {i}");
        }
    }

    /// With two contacts looked for, each frame's second contact live is
    /// the one the whole recording's pass gives filtered
    /// ([`crate::batch::pairs::session_pairs`]), frame by frame.
    #[test]
    fn a_second_contact_live_is_the_filtered_pass() {
        use crate::batch::pairs::{PairSeen, PairsOver, SingleSeen, session_pairs};
        let (robot, links) = lwr(&["lwr_5_link", "lwr_7_link"]);
        let settings = SynthSettings {
            duration_secs: 3.0,
            rate_hz: 25.0,
            press_secs: (1.0, 1.4),
            gap_secs: (0.2, 0.3),
            force_newtons: (15.0, 25.0),
            motion_rad: 0.0,
            contacts_at_once: 2,
            ..SynthSettings::default()
        };
        let frames = frames_of(&robot, &links, &settings, 3);
        let config = EstimatorConfig {
            surface_points: 1500,
            contacts_at_once: 2,
            ..EstimatorConfig::default()
        };
        // Written by the filter, read by the pass after it.
        let singles = std::cell::RefCell::new(vec![None; frames.len()]);
        let mut whole: Vec<Option<PairSeen>> = Vec::new();
        filtered_whole(
            (&robot, &links),
            &config,
            &frames,
            |i, update| singles.borrow_mut()[i] = SingleSeen::of(&update),
            |estimator, sequence| {
                let over = PairsOver::Filtered(config.second_contact_chain());
                whole = session_pairs(estimator, &robot, sequence, &singles.borrow(), &config.pair, over)
                    .unwrap_or_else(|(i, e)| panic!("frame {i}: {e}"))
                    .iter()
                    .map(|p| p.as_ref().map(PairSeen::of))
                    .collect();
            },
        );
        let worker = LiveFilterWorker::spawn(|| {});
        worker.start(LiveJob {
            generation: 1,
            robot: robot.clone(),
            frames: frames[..20].to_vec(),
            config: config.clone(),
            links,
        });
        worker.append(frames[20..].to_vec());
        let live = collect_live(&worker, 1, frames.len());
        let searched = whole.iter().filter(|p| p.is_some()).count();
        assert!(searched >= 5, "{searched} frames searched for a second contact");
        for (i, (w, l)) in whole.iter().zip(&live).enumerate() {
            assert_eq!(l.second, *w, "frame {i}");
        }
    }
}
