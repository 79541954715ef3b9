//! Settled frames on their way out in frame order, through the presses
//! (a press's frames wait for its fit), and the frames filtered and
//! waiting for their stretch; shared by both ways a recording is smoothed.

use std::collections::VecDeque;

use crate::core::estimate::estimator::{PendingUpdate, Update};
use crate::core::estimate::posterior::CompactPosterior;
use crate::core::estimate::summary::Summary;
use crate::core::over_time::press_queue::{Offered, PressJob, PressQueue};
use crate::core::robot::kinematics::RobotPose;

/// A frame settled by its press's fit or on its own.
pub(super) type Settled = (usize, Update, f64);

/// Fits a press as a task of `scope` that answers through `fitted`; or
/// now, where nothing runs beside this thread.
pub(super) fn press_fitter<'a: 'scope, 'scope>(
    scope: &rayon::Scope<'scope>,
    fitted: std::sync::mpsc::Sender<(usize, Vec<Settled>)>,
) -> impl Fn(PressJob<'a>, usize) -> Option<Vec<Settled>> {
    move |job, slot| {
        if rayon::current_num_threads() <= 1 {
            return Some(job.fit());
        }
        let fitted = fitted.clone();
        scope.spawn(move |_| {
            // The receiver outlives every task (the scope ends first).
            let _ = fitted.send((slot, job.fit()));
        });
        None
    }
}

/// Settled frames on their way out in frame order: a press that ends is
/// fitted as a task beside the filter (a fit is a fifth of a smoothed
/// recording's work, and depends on its own frames only), and the frames
/// after it wait for its fit.
pub(super) struct InOrder<'a, 's> {
    presses: PressQueue<'a>,
    /// Fits a press as a task (answering later, through `fitted`), or now.
    fit: &'s dyn Fn(PressJob<'a>, usize) -> Option<Vec<Settled>>,
    fitted: std::sync::mpsc::Receiver<(usize, Vec<Settled>)>,
    /// From slot `front` on: frames ready to leave, or a press in flight.
    slots: VecDeque<Option<Vec<Settled>>>,
    front: usize,
    /// The presses in flight: the bytes each one's frames hold, by slot.
    in_flight: std::collections::BTreeMap<usize, usize>,
}

impl<'a, 's> InOrder<'a, 's> {
    pub(super) fn new(
        presses: PressQueue<'a>,
        fit: &'s dyn Fn(PressJob<'a>, usize) -> Option<Vec<Settled>>,
        fitted: std::sync::mpsc::Receiver<(usize, Vec<Settled>)>,
    ) -> Self {
        Self {
            presses,
            fit,
            fitted,
            slots: VecDeque::new(),
            front: 0,
            in_flight: std::collections::BTreeMap::new(),
        }
    }

    /// Presses in flight.
    pub(super) fn presses_in_flight(&self) -> usize {
        self.in_flight.len()
    }

    /// Bytes the frames of the presses in flight hold.
    pub(super) fn bytes(&self) -> usize {
        self.in_flight.values().sum()
    }

    /// What the press queue hands on: a frame joins the last slot (or a
    /// new one after a press); a press takes a slot and is fitted.
    fn take(&mut self, offered: Offered<'a>) {
        match offered {
            Offered::Frame(i, update, ms) => match self.slots.back_mut() {
                Some(Some(frames)) => frames.push((i, update, ms)),
                _ => self.slots.push_back(Some(vec![(i, update, ms)])),
            },
            Offered::Press(job) => {
                let slot = self.front + self.slots.len();
                let bytes = job.bytes();
                if let Some(frames) = (self.fit)(job, slot) {
                    self.slots.push_back(Some(frames));
                } else {
                    self.slots.push_back(None);
                    self.in_flight.insert(slot, bytes);
                }
                // Frames after the press start a slot of their own.
                self.slots.push_back(Some(Vec::new()));
            }
        }
    }

    /// Frame `i`, smoothed, through the presses.
    pub(super) fn offer(&mut self, i: usize, settled: (Update, Option<Summary>), ms: f64) {
        let mut offered = Vec::new();
        self.presses.offer(i, settled, ms, &mut |o| offered.push(o));
        for o in offered {
            self.take(o);
        }
    }

    /// Takes in the presses fitted, then hands on every frame whose turn
    /// has come.
    pub(super) fn emit(&mut self, each: &mut impl FnMut(usize, Update, f64)) {
        while let Ok((slot, frames)) = self.fitted.try_recv() {
            self.accept(slot, frames);
        }
        // The last slot may still grow: it leaves only once a later one exists.
        while self.slots.len() > 1 && matches!(self.slots.front(), Some(Some(_))) {
            if let Some(Some(frames)) = self.slots.pop_front() {
                for (i, update, ms) in frames {
                    each(i, update, ms);
                }
            }
            self.front += 1;
        }
        if let [Some(frames)] = self.slots.make_contiguous() {
            for (i, update, ms) in frames.drain(..) {
                each(i, update, ms);
            }
        }
    }

    /// A press fitted: its frames take its slot.
    pub(super) fn accept(&mut self, slot: usize, frames: Vec<Settled>) {
        if let Some(place) = slot.checked_sub(self.front).and_then(|k| self.slots.get_mut(k)) {
            *place = Some(frames);
        }
        self.in_flight.remove(&slot);
    }

    /// The last press, ended: every frame has been offered.
    pub(super) fn last_press(&mut self) {
        let mut offered = Vec::new();
        self.presses.settle(&mut |o| offered.push(o));
        for o in offered {
            self.take(o);
        }
    }

    /// Hands on the last press and every frame, helping the fits in
    /// flight (or waiting) until they are done.
    pub(super) fn finish(&mut self, each: &mut impl FnMut(usize, Update, f64)) {
        self.last_press();
        loop {
            self.emit(each);
            if self.in_flight.is_empty() {
                break;
            }
            help_or_wait();
        }
        self.emit(each);
    }
}

/// A frame's own estimate while it waits for its smoothed belief: its
/// pose and its posterior, compacted (kept rather than computed again:
/// it is a third of a frame's work).
pub(super) struct WaitingFrame {
    pose: RobotPose,
    posterior: CompactPosterior,
}

impl WaitingFrame {
    pub(super) fn of(pending: PendingUpdate) -> Self {
        Self {
            pose: pending.pose,
            posterior: CompactPosterior::of(pending.posterior),
        }
    }

    pub(super) fn bytes(&self) -> usize {
        size_of::<Self>() + self.posterior.bytes()
    }

    pub(super) fn expand(self) -> PendingUpdate {
        PendingUpdate {
            pose: self.pose,
            posterior: self.posterior.expand(),
        }
    }
}

/// The frames filtered and not yet settled, in order: number, what each
/// has cost so far, its own estimate.
#[derive(Default)]
pub(super) struct Waiting {
    frames: VecDeque<(usize, f64, WaitingFrame)>,
    /// Bytes their posteriors hold.
    pub(super) bytes: usize,
}

impl Waiting {
    pub(super) fn push(&mut self, i: usize, ms: f64, frame: WaitingFrame) {
        self.bytes += frame.bytes();
        self.frames.push_back((i, ms, frame));
    }

    /// The first `n`, in order.
    pub(super) fn take(&mut self, n: usize) -> Vec<(usize, f64, WaitingFrame)> {
        let taken: Vec<_> = self.frames.drain(..n.min(self.frames.len())).collect();
        let freed: usize = taken.iter().map(|(_, _, f)| f.bytes()).sum();
        self.bytes = self.bytes.saturating_sub(freed);
        taken
    }
}

/// Runs a task of the pool on this thread if one waits, else yields.
pub(super) fn help_or_wait() {
    if rayon::yield_now() != Some(rayon::Yield::Executed) {
        std::thread::sleep(std::time::Duration::from_micros(200));
    }
}

/// Whether the smoother may take another block: nothing is in flight, or
/// what it counts (`bytes`: the store, the stretches in flight, the
/// frames waiting for them and the presses being fitted) is within
/// `limit_bytes` with no more stretches in flight than `threads`; and no
/// more presses are being fitted than `threads`. Both ways a recording is
/// smoothed hold the filter back by this rule.
pub(super) fn room_for_more(
    stretches_in_flight: usize,
    bytes: usize,
    presses_in_flight: usize,
    limit_bytes: usize,
    threads: usize,
) -> bool {
    (stretches_in_flight == 0 || (bytes <= limit_bytes && stretches_in_flight <= threads))
        && presses_in_flight <= threads
}
