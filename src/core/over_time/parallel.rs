//! A session's frames estimated in order with the per-frame work shared
//! among threads: a frame's likelihoods and its summary do not depend on
//! the temporal model's state, so blocks of frames compute them in
//! parallel and only the recursion (the filter's step, the smoother's
//! backward pass, the presses) runs in order. While the recursion takes
//! one block, the next block's likelihoods are computed beside it.
//!
//! Results leave in frame order, as the frames are settled: frames alone
//! and filtered frames block by block, smoothed frames stretch by stretch
//! ([`crate::core::over_time::stretches`]).

use std::ops::Range;
use std::time::Instant;

use rayon::prelude::*;

use crate::core::estimate::estimator::{Estimator, PendingUpdate, Update, elapsed_ms, finite};
use crate::core::estimate::settings::EstimateError;
use crate::core::estimate::summary::Summary;
use crate::core::over_time::frame::SequenceFrame;
use crate::core::over_time::in_order::{InOrder, Waiting, WaitingFrame, help_or_wait, press_fitter, room_for_more};
use crate::core::over_time::offsets::FrameLikelihood;
use crate::core::over_time::press_queue::PressQueue;
use crate::core::over_time::presses::FrictionGate;
use crate::core::over_time::smoother::FilterState;
use crate::core::over_time::stretches::{Piece, PreparedStep, StepPreparer, Stretch, StretchSmoother};
use crate::core::over_time::temporal::{Belief, TemporalError, TemporalModel};
use crate::core::robot::model::Robot;

/// Why a sequence could not be estimated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SequenceError {
    /// A frame's estimate failed.
    #[error("frame {frame}: {source}")]
    Frame {
        /// Frame number in the sequence (0-based).
        frame: usize,
        /// Why.
        source: EstimateError,
    },
    /// The temporal model refused a frame.
    #[error(transparent)]
    Temporal(#[from] TemporalError),
}

/// Frames per block: enough to keep every thread busy, few enough that a
/// block's posteriors (about 0.2 MB each at 5,000 points) stay small.
pub const BLOCK_FRAMES: usize = 64;

/// A frame's number, what its work gave, and the milliseconds it took.
pub(super) type Done<T> = (usize, Result<T, EstimateError>, f64);

/// What the caller is told, and asked, while a sequence runs: before
/// each block whether to go on, each frame's update in order, and each
/// frame whose estimate fails (true: leave it out and go on).
pub(crate) struct Callbacks<K, E, F> {
    pub keep_going: K,
    pub each: E,
    pub failed: F,
}

/// `work` of each frame of the block from `start`, in parallel, in order,
/// with the milliseconds each took.
fn in_parallel<T: Send>(
    frames: &[SequenceFrame],
    start: usize,
    work: impl Fn(&SequenceFrame) -> T + Sync + Send,
) -> Vec<(usize, T, f64)> {
    let range = block(start, frames.len());
    let first = range.start;
    frames.get(range).map_or_else(Vec::new, |block| {
        block
            .par_iter()
            .enumerate()
            .map(|(j, f)| {
                let t0 = Instant::now();
                let value = work(f);
                (first + j, value, elapsed_ms(t0))
            })
            .collect()
    })
}

/// The block of frames from `start`.
fn block(start: usize, frames: usize) -> Range<usize> {
    start.min(frames)..start.saturating_add(BLOCK_FRAMES).min(frames)
}

/// The frames of a block whose estimate succeeded; a failed one is left
/// out where `failed` says so, else it is the sequence's error.
pub(super) fn succeeded<T>(
    done: Vec<(usize, Result<T, EstimateError>, f64)>,
    failed: &mut impl FnMut(usize, &EstimateError) -> bool,
) -> Result<Vec<(usize, T, f64)>, SequenceError> {
    let mut out = Vec::with_capacity(done.len());
    for (i, result, ms) in done {
        match result {
            Ok(value) => out.push((i, value, ms)),
            Err(source) if failed(i, &source) => {}
            Err(source) => return Err(SequenceError::Frame { frame: i, source }),
        }
    }
    Ok(out)
}

/// Each frame alone. `Ok(false)` when `keep_going` said no.
pub(crate) fn alone(
    estimator: &Estimator,
    robot: &Robot,
    frames: &[SequenceFrame],
    mut calls: Callbacks<
        impl FnMut() -> bool,
        impl FnMut(usize, Update, f64),
        impl FnMut(usize, &EstimateError) -> bool,
    >,
) -> Result<bool, SequenceError> {
    let mut start = 0;
    while start < frames.len() {
        if !(calls.keep_going)() {
            return Ok(false);
        }
        let done = in_parallel(frames, start, |f| estimator.update(robot, f.joint_positions, f.tau));
        for (i, update, ms) in succeeded(done, &mut calls.failed)? {
            (calls.each)(i, update, ms);
        }
        start += BLOCK_FRAMES;
    }
    Ok(true)
}

/// Each frame's likelihoods for the block from `start`, with its pending
/// update as `keep` makes it (the smoother compacts it here, in
/// parallel, so that the filter's thread only stores it).
fn likelihoods<W: Send>(
    (estimator, robot, frames): (&Estimator, &Robot, &[SequenceFrame]),
    start: usize,
    keep: impl Fn(PendingUpdate) -> W + Sync + Send,
) -> Vec<Done<(W, FrameLikelihood)>> {
    in_parallel(frames, start, |f| {
        estimator
            .update_for_sequence(robot, f.joint_positions, f.tau)
            .map(|(pending, likelihood)| (keep(pending), likelihood))
    })
}

/// A block's frames with the step each closes, or why the frames after
/// them were not taken.
pub(super) struct PreparedBlock {
    pub(super) done: Vec<Done<(WaitingFrame, Option<PreparedStep>)>>,
    /// A frame whose time the steps refused: the frames before it are in
    /// `done`, the rest of the block is not.
    pub(super) refused: Option<TemporalError>,
}

/// The likelihoods of the block from `start` (in parallel) and the steps
/// its frames close (in order): all of a block's work that does not wait
/// for the filter. A frame whose estimate failed joins no step.
fn prepared(
    sequence: (&Estimator, &Robot, &[SequenceFrame]),
    start: usize,
    preparer: &mut StepPreparer,
) -> PreparedBlock {
    into_steps(likelihoods(sequence, start, WaitingFrame::of), sequence.2, preparer)
}

/// One frame's likelihoods, its pending update compacted, and the
/// milliseconds they took.
pub(super) fn frame_likelihood(
    (estimator, robot, frames): (&Estimator, &Robot, &[SequenceFrame]),
    i: usize,
) -> Option<Done<(WaitingFrame, FrameLikelihood)>> {
    let f = frames.get(i)?;
    let t0 = Instant::now();
    let result = estimator
        .update_for_sequence(robot, f.joint_positions, f.tau)
        .map(|(pending, likelihood)| (WaitingFrame::of(pending), likelihood));
    Some((i, result, elapsed_ms(t0)))
}

/// A block's frames, with their likelihoods in order, gathered into the
/// steps they close.
pub(super) fn into_steps(
    block: Vec<Done<(WaitingFrame, FrameLikelihood)>>,
    frames: &[SequenceFrame],
    preparer: &mut StepPreparer,
) -> PreparedBlock {
    let mut done = Vec::with_capacity(block.len());
    for (i, result, ms) in block {
        let Ok((pending, likelihood)) = result else {
            done.push((i, result.map(|(pending, _)| (pending, None)), ms));
            continue;
        };
        let t0 = Instant::now();
        let t_secs = frames.get(i).map_or(f64::NAN, |f| f.t_secs);
        match preparer.push(t_secs, likelihood) {
            Ok(step) => done.push((i, Ok((pending, step)), ms + elapsed_ms(t0))),
            Err(refused) => {
                return PreparedBlock {
                    done,
                    refused: Some(refused),
                };
            }
        }
    }
    PreparedBlock { done, refused: None }
}

/// The filter's part of a block: its steps taken in order, each frame
/// then waiting for its stretch with what it has cost; the pieces cut.
fn filter_block(
    smoother: &mut StretchSmoother,
    waiting: &mut Waiting,
    ready: Vec<(usize, (WaitingFrame, Option<PreparedStep>), f64)>,
    refused: Option<TemporalError>,
) -> Result<Vec<Piece>, TemporalError> {
    let mut cut = Vec::new();
    for (i, (pending, step), ms) in ready {
        let t0 = Instant::now();
        if let Some(step) = step {
            cut.extend(smoother.push_step(step)?);
        }
        waiting.push(i, ms + elapsed_ms(t0), pending);
    }
    refused.map_or(Ok(cut), Err)
}

/// Each frame with the frames before it (as live). `Ok(false)` when
/// `keep_going` said no.
pub(crate) fn filter(
    estimator: &Estimator,
    robot: &Robot,
    model: &TemporalModel,
    frames: &[SequenceFrame],
    mut calls: Callbacks<
        impl FnMut() -> bool,
        impl FnMut(usize, Update, f64),
        impl FnMut(usize, &EstimateError) -> bool,
    >,
) -> Result<bool, SequenceError> {
    let mut state = FilterState::default();
    let mut gate = FrictionGate::default();
    let slide = model.settings().slide_m_per_sqrt_s;
    let mut start = 0;
    let mut done = likelihoods((estimator, robot, frames), start, |p| p);
    while !done.is_empty() {
        if !(calls.keep_going)() {
            return Ok(false);
        }
        let ready = succeeded(done, &mut calls.failed)?;
        start += BLOCK_FRAMES;
        // The recursion in order, the next block's likelihoods beside it.
        let (stepped, next) = rayon::join(
            || -> Result<Vec<(usize, PendingUpdate, Belief, f64)>, TemporalError> {
                ready
                    .into_iter()
                    .map(|(i, (pending, likelihood), ms)| {
                        let t0 = Instant::now();
                        let t_secs = frames.get(i).map_or(f64::NAN, |f| f.t_secs);
                        let belief = state.step(model, t_secs, &likelihood)?.clone();
                        Ok((i, pending, belief, ms + elapsed_ms(t0)))
                    })
                    .collect()
            },
            || likelihoods((estimator, robot, frames), start, |p| p),
        );
        done = next;
        let summarised: Vec<(usize, Update, f64)> = stepped?
            .into_par_iter()
            .filter_map(|(i, pending, belief, ms)| {
                let t0 = Instant::now();
                let f = frames.get(i)?;
                let update = estimator.with_belief(robot, pending, f.tau, &belief);
                Some((i, update, ms + elapsed_ms(t0)))
            })
            .collect();
        for (i, mut update, ms) in summarised {
            let Some(f) = frames.get(i) else {
                continue;
            };
            let t0 = Instant::now();
            estimator.gate_friction(robot, &mut update, (i, f.t_secs, f.tau), slide, &mut gate);
            match finite(update) {
                Ok(update) => (calls.each)(i, update, ms + elapsed_ms(t0)),
                Err(source) if (calls.failed)(i, &source) => {}
                Err(source) => return Err(SequenceError::Frame { frame: i, source }),
            }
        }
    }
    Ok(true)
}

/// Each frame with the whole sequence, in stretches of bounded memory.
/// The forward filter runs in order on the calling thread; each piece it
/// cuts is smoothed (its backward pass) as a task of its own, beside it;
/// smoothed stretches are settled in order. `Ok(false)` when
/// `keep_going` said no.
pub(crate) fn smooth(
    estimator: &Estimator,
    robot: &Robot,
    model: &TemporalModel,
    frames: &[SequenceFrame],
    mut calls: Callbacks<
        impl FnMut() -> bool,
        impl FnMut(usize, Update, f64),
        impl FnMut(usize, &EstimateError) -> bool,
    >,
) -> Result<bool, SequenceError> {
    let each = &mut calls.each;
    rayon::in_place_scope(|scope| -> Result<bool, SequenceError> {
        let (done_tx, done_rx) = std::sync::mpsc::channel::<(usize, Stretch, f64, usize)>();
        let (press_tx, press_rx) = std::sync::mpsc::channel::<(usize, Vec<(usize, Update, f64)>)>();
        let fit_press = press_fitter(scope, press_tx);
        let queue = PressQueue::new(estimator, robot, frames, model.settings().slide_m_per_sqrt_s);
        let mut out = InOrder::new(queue, &fit_press, press_rx);
        let mut smoother = StretchSmoother::new(model, model.store_limit_bytes());
        let mut pieces = Pieces::default();
        // Smooths a piece beside the filter.
        let spawn = |piece: Piece, pieces: &mut Pieces| {
            let number = pieces.spawned;
            pieces.spawned += 1;
            if rayon::current_num_threads() <= 1 {
                // Nothing runs beside this thread: smooth it now.
                let t0 = Instant::now();
                let bytes = piece.bytes();
                let stretch = piece.smooth(model);
                pieces.smoothed.insert(number, (stretch, elapsed_ms(t0), bytes));
                pieces.bytes_in_flight += bytes;
                return;
            }
            pieces.bytes_in_flight += piece.bytes();
            let done_tx = done_tx.clone();
            scope.spawn(move |_| {
                let t0 = Instant::now();
                let bytes = piece.bytes();
                let stretch = piece.smooth(model);
                // The receiver outlives every task (the scope ends first).
                let _ = done_tx.send((number, stretch, elapsed_ms(t0), bytes));
            });
        };
        // The frames pushed and not yet settled, with what each has cost.
        let mut waiting = Waiting::default();
        let mut start = 0;
        let mut preparer = StepPreparer::new(model);
        let mut next = prepared((estimator, robot, frames), start, &mut preparer);
        let limit = model.store_limit_bytes();
        let threads = rayon::current_num_threads();
        while !next.done.is_empty() || next.refused.is_some() {
            if !(calls.keep_going)() {
                return Ok(false);
            }
            let PreparedBlock { done, refused } = next;
            let ready = succeeded(done, &mut calls.failed)?;
            start += BLOCK_FRAMES;
            // The filter takes this block's steps while the next block's
            // likelihoods and steps are made beside it.
            let (cut, after) = rayon::join(
                || filter_block(&mut smoother, &mut waiting, ready, refused),
                || prepared((estimator, robot, frames), start, &mut preparer),
            );
            next = after;
            for piece in cut? {
                spawn(piece, &mut pieces);
            }
            // Settle what is smoothed; while the pieces and presses in
            // flight and the store hold more than the limit, help them.
            let room = |pieces: &Pieces, waiting: &Waiting, out: &InOrder| {
                let bytes = smoother.held_bytes() + pieces.bytes_in_flight + waiting.bytes + out.bytes();
                room_for_more(
                    pieces.spawned - pieces.settled,
                    bytes,
                    out.presses_in_flight(),
                    limit,
                    threads,
                )
            };
            if !pieces.settle_until(
                &done_rx,
                room,
                (estimator, robot, frames),
                (&mut waiting, &mut out),
                (&mut calls.keep_going, &mut *each, &mut calls.failed),
            )? {
                return Ok(false);
            }
        }
        let last = preparer.finish().map(|step| smoother.push_step(step)).transpose()?;
        for piece in last.into_iter().flatten().chain(smoother.finish()?) {
            spawn(piece, &mut pieces);
        }
        if !pieces.settle_until(
            &done_rx,
            |pieces, _, _| pieces.settled == pieces.spawned,
            (estimator, robot, frames),
            (&mut waiting, &mut out),
            (&mut calls.keep_going, &mut *each, &mut calls.failed),
        )? {
            return Ok(false);
        }
        out.finish(each);
        Ok(true)
    })
}

/// The pieces of a smoothed recording under way: spawned, smoothed and
/// waiting for their turn, settled.
#[derive(Default)]
struct Pieces {
    spawned: usize,
    settled: usize,
    bytes_in_flight: usize,
    /// Smoothed and not yet settled, by number, with the backward pass's
    /// ms and the bytes its piece held.
    smoothed: std::collections::BTreeMap<usize, (Stretch, f64, usize)>,
}

impl Pieces {
    /// Settles smoothed stretches as their turn comes, helping the tasks
    /// (or waiting) until `enough`. `Ok(false)` when `keep_going` said no.
    fn settle_until(
        &mut self,
        done: &std::sync::mpsc::Receiver<(usize, Stretch, f64, usize)>,
        enough: impl Fn(&Self, &Waiting, &InOrder) -> bool,
        sequence: (&Estimator, &Robot, &[SequenceFrame]),
        (waiting, out): (&mut Waiting, &mut InOrder),
        (keep_going, each, failed): (
            &mut impl FnMut() -> bool,
            &mut impl FnMut(usize, Update, f64),
            &mut impl FnMut(usize, &EstimateError) -> bool,
        ),
    ) -> Result<bool, SequenceError> {
        loop {
            self.receive(done);
            if !self.settle_ready(sequence, waiting, out, (&mut *keep_going, &mut *each, &mut *failed))? {
                return Ok(false);
            }
            out.emit(each);
            if enough(self, waiting, out) {
                return Ok(true);
            }
            help_or_wait();
        }
    }

    /// Takes in what the tasks have smoothed.
    fn receive(&mut self, done: &std::sync::mpsc::Receiver<(usize, Stretch, f64, usize)>) {
        for (number, stretch, ms, bytes) in done.try_iter() {
            self.smoothed.insert(number, (stretch, ms, bytes));
        }
    }

    /// Settles the smoothed stretches whose turn it is, in order.
    fn settle_ready(
        &mut self,
        sequence: (&Estimator, &Robot, &[SequenceFrame]),
        waiting: &mut Waiting,
        out: &mut InOrder,
        calls: (
            &mut impl FnMut() -> bool,
            &mut impl FnMut(usize, Update, f64),
            &mut impl FnMut(usize, &EstimateError) -> bool,
        ),
    ) -> Result<bool, SequenceError> {
        let (keep_going, each, failed) = calls;
        while let Some((stretch, backward_ms, bytes)) = self.smoothed.remove(&self.settled) {
            self.settled += 1;
            let cont = settle_stretch(
                sequence,
                (&stretch, backward_ms),
                waiting,
                out,
                (keep_going, each, failed),
            )?;
            self.bytes_in_flight = self.bytes_in_flight.saturating_sub(bytes);
            if !cont {
                return Ok(false);
            }
        }
        Ok(true)
    }
}

/// A smoothed stretch's frames (the first `stretch.len()` of `waiting`):
/// each frame's own posterior seen through its smoothed belief, in
/// parallel, then offered to the presses in order. `Ok(false)` when
/// `keep_going` said no.
fn settle_stretch(
    (estimator, robot, frames): (&Estimator, &Robot, &[SequenceFrame]),
    (stretch, backward_ms): (&Stretch, f64),
    waiting: &mut Waiting,
    out: &mut InOrder,
    (keep_going, each, failed): (
        &mut impl FnMut() -> bool,
        &mut impl FnMut(usize, Update, f64),
        &mut impl FnMut(usize, &EstimateError) -> bool,
    ),
) -> Result<bool, SequenceError> {
    let share_ms = backward_ms / stretch.len().max(1) as f64;
    let mut entries = waiting.take(stretch.len());
    let mut c = 0;
    while !entries.is_empty() {
        if !keep_going() {
            return Ok(false);
        }
        let rest = entries.split_off(BLOCK_FRAMES.min(entries.len()));
        let chunk = std::mem::replace(&mut entries, rest);
        let done: Vec<Done<(Update, Option<Summary>)>> = chunk
            .into_par_iter()
            .enumerate()
            .filter_map(|(j, entry)| {
                settle_frame(
                    (estimator, robot, frames),
                    stretch,
                    c * BLOCK_FRAMES + j,
                    entry,
                    share_ms,
                )
            })
            .collect();
        c += 1;
        for (i, settled, ms) in succeeded(done, failed)? {
            out.offer(i, settled, ms);
        }
        out.emit(each);
    }
    Ok(true)
}

/// A waiting frame's own posterior seen through its smoothed belief (the
/// `k`-th of `stretch`), with the milliseconds it has cost in all.
pub(super) fn settle_frame(
    (estimator, robot, frames): (&Estimator, &Robot, &[SequenceFrame]),
    stretch: &Stretch,
    k: usize,
    (i, ms, waiting): (usize, f64, WaitingFrame),
    share_ms: f64,
) -> Option<Done<(Update, Option<Summary>)>> {
    let t0 = Instant::now();
    let f = frames.get(i)?;
    let pending = waiting.expand();
    let belief = stretch.belief(k)?;
    let alone = estimator.summary_alone(robot, &pending, f.tau, &belief);
    let update = estimator.with_belief_as(robot, pending, f.tau, &belief, !estimator.fits_presses());
    Some((i, Ok((update, alone)), ms + share_ms + elapsed_ms(t0)))
}
