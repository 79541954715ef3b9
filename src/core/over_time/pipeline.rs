//! A recording smoothed on many cores: the forward filter runs on a thread
//! of its own, outside the pool, so that it never waits for another task.
//!
//! In [`crate::core::over_time::parallel`] the filter runs on the calling
//! thread, and a pool thread that waits (for the likelihoods beside it, or
//! for room in memory) runs any task the pool holds: a stretch's backward
//! pass (half a second for three seconds of a 1 kHz recording) or a press's
//! fit. With many threads the filter is the part that runs in order, so
//! every such task on its thread stalls the whole pool (on 16 threads the
//! pool was busy 27 % of the time). Here three threads take the parts in
//! order and run no task of the pool:
//! - the *feeder* hands each block's likelihoods to the pool, frame by
//!   frame, and gathers them into the model's steps;
//! - the *filter* takes the steps and cuts the stretches, whose backward
//!   passes it hands to the pool;
//! - the calling thread settles the stretches (their frames' summaries, in
//!   the pool), offers the frames to the presses (fits in the pool) and
//!   hands them on in order. It gives the feeder a block only while the
//!   memory limit has room, so the filter waits where memory is short.
//!
//! The estimates are the same as on one thread, frame for frame.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, Sender, SyncSender, TryRecvError, channel, sync_channel};
use std::time::Instant;

use crate::core::estimate::estimator::{Estimator, Update, elapsed_ms};
use crate::core::estimate::settings::EstimateError;
use crate::core::estimate::summary::Summary;
use crate::core::over_time::frame::SequenceFrame;
use crate::core::over_time::in_order::{InOrder, Settled, Waiting, WaitingFrame, room_for_more};
use crate::core::over_time::parallel::{
    BLOCK_FRAMES, Callbacks, Done, PreparedBlock, SequenceError, frame_likelihood, into_steps, settle_frame, succeeded,
};
use crate::core::over_time::press_queue::{PressJob, PressQueue};
use crate::core::over_time::stretches::{PreparedStep, StepPreparer, Stretch, StretchSmoother};
use crate::core::over_time::temporal::{TemporalError, TemporalModel};
use crate::core::robot::model::Robot;

/// Fewest threads in the pool for this way: the calling thread only
/// waits and hands on, so with fewer the pool would have one worker.
pub(crate) const MIN_THREADS: usize = 3;

/// Blocks the feeder may be ahead of the filter.
const AHEAD_BLOCKS: usize = 4;

/// Frames in one task of the pool: a block's likelihoods, or a stretch's
/// summaries (a few milliseconds each).
const TASK_FRAMES: usize = 8;

/// What the filter's thread tells the calling thread, block by block.
struct Filtered {
    /// The block's frames, in order, with their own estimates (or why
    /// there is none) and what each has cost.
    frames: Vec<Done<WaitingFrame>>,
    /// Stretches cut: number and bytes (their backward passes are tasks).
    pieces: Vec<(usize, usize)>,
    /// Bytes the filter's store holds.
    held_bytes: usize,
    /// Why the filter stopped, if it did.
    refused: Option<TemporalError>,
    /// The filter has taken its last step.
    last: bool,
}

/// What the calling thread waits for.
enum Event {
    Filtered(Filtered),
    /// A stretch's backward pass: number, stretch, ms.
    Smoothed(usize, Stretch, f64),
    /// A task's summaries: its number in the order frames leave.
    Settled(usize, Vec<SettledDone>),
    /// A press fitted: its slot and its frames.
    Fitted(usize, Vec<Settled>),
    /// A task or thread stopped without its answer (it panicked): the
    /// calling thread stops waiting, and the scope passes the panic on.
    Stopped,
}

/// Sends [`Event::Stopped`] if dropped while its thread unwinds, so that
/// a panic anywhere ends the wait for the answer it took with it.
struct StopOnPanic(Sender<Event>);

impl Drop for StopOnPanic {
    fn drop(&mut self) {
        if std::thread::panicking() {
            // The calling thread may have stopped already.
            let _ = self.0.send(Event::Stopped);
        }
    }
}

/// How long each thread in order waited, and for what, ns: which part
/// holds the others back (`RUST_LOG=proprioscope=debug` prints it once a
/// recording is smoothed; the `device` runs read it).
#[derive(Default)]
struct Waits {
    /// The feeder, for a block granted (room in memory, or the filter
    /// [`AHEAD_BLOCKS`] behind).
    feeder_credit: AtomicU64,
    /// The feeder, for a block's likelihoods from the pool.
    feeder_likelihoods: AtomicU64,
    /// The feeder, for the filter to take a block.
    feeder_filter: AtomicU64,
    /// The filter, for the feeder's next block.
    filter_feed: AtomicU64,
    /// The calling thread, for any event.
    calling_events: AtomicU64,
}

impl Waits {
    /// `what()`, its time added to `to`.
    fn timed<T>(to: &AtomicU64, what: impl FnOnce() -> T) -> T {
        let t0 = Instant::now();
        let out = what();
        to.fetch_add(
            u64::try_from(t0.elapsed().as_nanos()).unwrap_or(u64::MAX),
            Ordering::Relaxed,
        );
        out
    }

    fn log(&self, wall_secs: f64) {
        let secs = |a: &AtomicU64| a.load(Ordering::Relaxed) as f64 * 1e-9;
        log::debug!(
            "smoothed in {wall_secs:.2} s on {} threads; waited: feeder {:.2} s for room, {:.2} s for likelihoods, \
             {:.2} s for the filter; filter {:.2} s for steps; calling thread {:.2} s for the others",
            rayon::current_num_threads(),
            secs(&self.feeder_credit),
            secs(&self.feeder_likelihoods),
            secs(&self.feeder_filter),
            secs(&self.filter_feed),
            secs(&self.calling_events),
        );
    }
}

/// What the feeder hands the filter.
enum Feed {
    Block(PreparedBlock),
    /// The open step, closed after the last frame.
    Last(Option<PreparedStep>),
}

/// A frame's smoothed update and its summary alone, as a task gives them.
type SettledDone = Done<(Update, Option<Summary>)>;

type Sequence<'a> = (&'a Estimator, &'a Robot, &'a [SequenceFrame<'a>]);

/// Each frame with the whole sequence, as
/// [`crate::core::over_time::parallel`]'s smoother gives it, with the
/// parts in order on threads of their own. `Ok(false)` when `keep_going`
/// said no.
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
    let sequence: Sequence<'_> = (estimator, robot, frames);
    let each = &mut calls.each;
    let waits = Waits::default();
    let t0 = Instant::now();
    let waits_ref = &waits;
    let out = rayon::in_place_scope(|scope| {
        std::thread::scope(|threads| -> Result<bool, SequenceError> {
            let (events_tx, events) = channel::<Event>();
            let (credits_tx, credits) = channel::<()>();
            let (feed_tx, feed) = sync_channel::<Feed>(AHEAD_BLOCKS);
            let feeder_events = events_tx.clone();
            threads.spawn(move || feeder(scope, sequence, model, (&credits, &feed_tx), feeder_events, waits_ref));
            let filter_events = events_tx.clone();
            threads.spawn(move || filter_thread(scope, model, &feed, &filter_events, waits_ref));
            let fit = fitter(scope, events_tx.clone());
            // Fits answer through the events; this channel stays empty.
            let (_unused, fitted) = channel();
            let queue = PressQueue::new(estimator, robot, frames, model.settings().slide_m_per_sqrt_s);
            let mut state = Calling::new(InOrder::new(queue, &fit, fitted), model.store_limit_bytes());
            state.ask(&credits_tx, frames.len());
            while !state.finished() {
                let Ok(event) = Waits::timed(&waits_ref.calling_events, || events.recv()) else {
                    break;
                };
                match event {
                    Event::Filtered(block) => {
                        if !(calls.keep_going)() {
                            return Ok(false);
                        }
                        state.filtered(block, &mut calls.failed)?;
                    }
                    Event::Smoothed(number, stretch, ms) => {
                        state.smoothed.insert(number, (stretch, ms));
                    }
                    Event::Settled(task, done) => {
                        state.settled_tasks.insert(task, done);
                    }
                    Event::Fitted(slot, frames) => state.out.accept(slot, frames),
                    Event::Stopped => return Ok(false),
                }
                state.settle(scope, sequence, &events_tx);
                state.hand_on(each, &mut calls.failed)?;
                state.ask(&credits_tx, frames.len());
            }
            state.out.last_press();
            state.out.emit(each);
            while state.out.presses_in_flight() > 0 {
                let Ok(event) = events.recv() else { break };
                match event {
                    Event::Fitted(slot, frames) => state.out.accept(slot, frames),
                    Event::Stopped => return Ok(false),
                    _ => {}
                }
                state.out.emit(each);
            }
            Ok(true)
        })
    });
    waits.log(t0.elapsed().as_secs_f64());
    out
}

/// Fits a press as a task of `scope` that answers through the events.
fn fitter<'a: 'scope, 'scope>(
    scope: &rayon::Scope<'scope>,
    events: Sender<Event>,
) -> impl Fn(PressJob<'a>, usize) -> Option<Vec<Settled>> {
    move |job, slot| {
        let events = events.clone();
        scope.spawn(move |_| {
            let _alarm = StopOnPanic(events.clone());
            // The receiver outlives every task (the scope ends first).
            let _ = events.send(Event::Fitted(slot, job.fit()));
        });
        None
    }
}

/// The calling thread's part: what is under way and waiting.
struct Calling<'a, 's> {
    out: InOrder<'a, 's>,
    waiting: Waiting,
    /// Backward passes done and not yet settling, by number, with their ms.
    smoothed: BTreeMap<usize, (Stretch, f64)>,
    /// Bytes of each piece cut and not yet settled, by number.
    piece_bytes: BTreeMap<usize, usize>,
    pieces_cut: usize,
    /// Pieces whose summaries are under way or done (the first ones).
    pieces_settling: usize,
    /// Summary tasks done and not yet handed on, by number.
    settled_tasks: BTreeMap<usize, Vec<SettledDone>>,
    tasks_spawned: usize,
    tasks_done: usize,
    /// Each piece's last task, with the piece: its bytes go with it.
    releases: BTreeMap<usize, usize>,
    held_bytes: usize,
    blocks_asked: usize,
    blocks_filtered: usize,
    filter_done: bool,
    limit_bytes: usize,
    threads: usize,
}

impl<'a, 's> Calling<'a, 's> {
    fn new(out: InOrder<'a, 's>, limit_bytes: usize) -> Self {
        Self {
            out,
            waiting: Waiting::default(),
            smoothed: BTreeMap::new(),
            piece_bytes: BTreeMap::new(),
            pieces_cut: 0,
            pieces_settling: 0,
            settled_tasks: BTreeMap::new(),
            tasks_spawned: 0,
            tasks_done: 0,
            releases: BTreeMap::new(),
            held_bytes: 0,
            blocks_asked: 0,
            blocks_filtered: 0,
            filter_done: false,
            limit_bytes,
            threads: rayon::current_num_threads(),
        }
    }

    /// Every frame filtered, settled and offered to the presses.
    fn finished(&self) -> bool {
        self.filter_done && self.pieces_settling == self.pieces_cut && self.tasks_done == self.tasks_spawned
    }

    /// Whether memory and the tasks under way leave room for another
    /// block (as [`crate::core::over_time::parallel`] counts it).
    fn room(&self) -> bool {
        let bytes = self.held_bytes + self.piece_bytes.values().sum::<usize>() + self.waiting.bytes + self.out.bytes();
        room_for_more(
            self.piece_bytes.len(),
            bytes,
            self.out.presses_in_flight(),
            self.limit_bytes,
            self.threads,
        )
    }

    /// Gives the feeder blocks while there is room, up to
    /// [`AHEAD_BLOCKS`] ahead of the filter.
    fn ask(&mut self, credits: &Sender<()>, frames: usize) {
        let blocks = frames.div_ceil(BLOCK_FRAMES);
        while self.blocks_asked < blocks && self.blocks_asked - self.blocks_filtered < AHEAD_BLOCKS && self.room() {
            // A feeder that has stopped asks for nothing more.
            let _ = credits.send(());
            self.blocks_asked += 1;
        }
    }

    /// A block filtered: its frames wait for their stretches.
    fn filtered(
        &mut self,
        block: Filtered,
        failed: &mut impl FnMut(usize, &EstimateError) -> bool,
    ) -> Result<(), SequenceError> {
        self.blocks_filtered += 1;
        for (i, frame, ms) in succeeded(block.frames, failed)? {
            self.waiting.push(i, ms, frame);
        }
        for (number, bytes) in block.pieces {
            self.piece_bytes.insert(number, bytes);
            self.pieces_cut = self.pieces_cut.max(number + 1);
        }
        self.held_bytes = block.held_bytes;
        if let Some(refused) = block.refused {
            return Err(refused.into());
        }
        self.filter_done |= block.last;
        Ok(())
    }

    /// Hands the summaries of each smoothed stretch whose turn it is to
    /// the pool, a few frames a task.
    fn settle<'scope>(&mut self, scope: &rayon::Scope<'scope>, sequence: Sequence<'scope>, events: &Sender<Event>) {
        while self.pieces_settling < self.pieces_cut
            && let Some((stretch, backward_ms)) = self.smoothed.remove(&self.pieces_settling)
        {
            let number = self.pieces_settling;
            self.pieces_settling += 1;
            let share_ms = backward_ms / stretch.len().max(1) as f64;
            let mut entries = self.waiting.take(stretch.len());
            let stretch = Arc::new(stretch);
            let mut first = 0;
            while !entries.is_empty() {
                let rest = entries.split_off(TASK_FRAMES.min(entries.len()));
                let chunk = std::mem::replace(&mut entries, rest);
                let task = self.tasks_spawned;
                self.tasks_spawned += 1;
                let (stretch, events) = (Arc::clone(&stretch), events.clone());
                let offset = first;
                first += chunk.len();
                scope.spawn(move |_| {
                    let _alarm = StopOnPanic(events.clone());
                    let done = chunk
                        .into_iter()
                        .enumerate()
                        .filter_map(|(j, entry)| settle_frame(sequence, &stretch, offset + j, entry, share_ms))
                        .collect();
                    // The receiver outlives every task (the scope ends first).
                    let _ = events.send(Event::Settled(task, done));
                });
            }
            match self.tasks_spawned.checked_sub(1) {
                Some(last) if first > 0 => {
                    self.releases.insert(last, number);
                }
                _ => {
                    self.piece_bytes.remove(&number);
                }
            }
        }
    }

    /// Offers the summaries done, in order, to the presses, and hands on
    /// every frame whose turn has come.
    fn hand_on(
        &mut self,
        each: &mut impl FnMut(usize, Update, f64),
        failed: &mut impl FnMut(usize, &EstimateError) -> bool,
    ) -> Result<(), SequenceError> {
        while let Some(done) = self.settled_tasks.remove(&self.tasks_done) {
            if let Some(number) = self.releases.remove(&self.tasks_done) {
                self.piece_bytes.remove(&number);
            }
            self.tasks_done += 1;
            for (i, settled, ms) in succeeded(done, failed)? {
                self.out.offer(i, settled, ms);
            }
        }
        self.out.emit(each);
        Ok(())
    }
}

/// The feeder's thread: each block granted, its likelihoods computed by
/// the pool, then gathered into the model's steps in order for the filter.
fn feeder<'scope>(
    scope: &rayon::Scope<'scope>,
    sequence: Sequence<'scope>,
    model: &TemporalModel,
    (credits, feed): (&Receiver<()>, &SyncSender<Feed>),
    events: Sender<Event>,
    waits: &Waits,
) {
    let alarm = StopOnPanic(events);
    let events = &alarm.0;
    let frames = sequence.2;
    let mut preparer = StepPreparer::new(model);
    let mut under_way = std::collections::VecDeque::new();
    let mut start = 0;
    loop {
        while start < frames.len() {
            let granted = if under_way.is_empty() {
                Waits::timed(&waits.feeder_credit, || credits.recv()).is_ok()
            } else {
                match credits.try_recv() {
                    Ok(()) => true,
                    Err(TryRecvError::Empty) => break,
                    Err(TryRecvError::Disconnected) => false,
                }
            };
            if !granted {
                return;
            }
            under_way.push_back(likelihoods(scope, sequence, start));
            start += BLOCK_FRAMES;
        }
        let Some((parts, tasks)) = under_way.pop_front() else {
            break;
        };
        let mut parts: Vec<(usize, Vec<LikelihoodDone>)> =
            Waits::timed(&waits.feeder_likelihoods, || parts.iter().take(tasks).collect());
        if parts.len() < tasks {
            // A task did not answer: it panicked, and the scope says so.
            let _ = events.send(Event::Stopped);
            return;
        }
        parts.sort_unstable_by_key(|(task, _)| *task);
        let block = parts.into_iter().flat_map(|(_, done)| done).collect();
        let prepared = into_steps(block, frames, &mut preparer);
        let stop = prepared.refused.is_some();
        if !Waits::timed(&waits.feeder_filter, || feed.send(Feed::Block(prepared)).is_ok()) || stop {
            return;
        }
    }
    // The filter is gone only if the calling thread has stopped.
    let _ = feed.send(Feed::Last(preparer.finish()));
}

/// A frame's likelihoods and compacted update, as a task gives them.
type LikelihoodDone = Done<(WaitingFrame, crate::core::over_time::offsets::FrameLikelihood)>;

/// The likelihoods of the block from `start` as tasks of the pool: where
/// they answer (task number, frames), and how many tasks.
fn likelihoods<'scope>(
    scope: &rayon::Scope<'scope>,
    sequence: Sequence<'scope>,
    start: usize,
) -> (Receiver<(usize, Vec<LikelihoodDone>)>, usize) {
    let end = start.saturating_add(BLOCK_FRAMES).min(sequence.2.len());
    let (tx, rx) = channel();
    let mut tasks = 0;
    for (task, first) in (start..end).step_by(TASK_FRAMES).enumerate() {
        let last = first.saturating_add(TASK_FRAMES).min(end);
        let tx = tx.clone();
        scope.spawn(move |_| {
            // A panic here drops `tx` unanswered; the feeder sees it.
            let done = (first..last).filter_map(|i| frame_likelihood(sequence, i)).collect();
            // The feeder waits for every task of its block.
            let _ = tx.send((task, done));
        });
        tasks += 1;
    }
    (rx, tasks)
}

/// The filter's thread: each block's steps in order, the stretches cut
/// handed to the pool for their backward passes.
fn filter_thread<'scope>(
    scope: &rayon::Scope<'scope>,
    model: &'scope TemporalModel,
    feed: &Receiver<Feed>,
    events: &Sender<Event>,
    waits: &Waits,
) {
    let _alarm = StopOnPanic(events.clone());
    let mut smoother = StretchSmoother::new(model, model.store_limit_bytes());
    let mut number = 0;
    let mut cut = |piece: crate::core::over_time::stretches::Piece, pieces: &mut Vec<(usize, usize)>| {
        let (n, bytes, events) = (number, piece.bytes(), events.clone());
        number += 1;
        pieces.push((n, bytes));
        scope.spawn(move |_| {
            let _alarm = StopOnPanic(events.clone());
            let t0 = Instant::now();
            let stretch = piece.smooth(model);
            // The receiver outlives every task (the scope ends first).
            let _ = events.send(Event::Smoothed(n, stretch, elapsed_ms(t0)));
        });
    };
    let last = loop {
        let Ok(item) = Waits::timed(&waits.filter_feed, || feed.recv()) else {
            // The feeder stopped: the calling thread has, or a task
            // panicked (the feeder has said so).
            return;
        };
        let PreparedBlock { done, refused } = match item {
            Feed::Block(block) => block,
            Feed::Last(step) => break step,
        };
        let mut frames = Vec::with_capacity(done.len());
        let mut pieces = Vec::new();
        let mut stopped = refused;
        for (i, result, ms) in done {
            match result {
                Ok((waiting, step)) => {
                    let t0 = Instant::now();
                    if let Some(step) = step
                        && stopped.is_none()
                    {
                        match smoother.push_step(step) {
                            Ok(piece) => piece.into_iter().for_each(|p| cut(p, &mut pieces)),
                            Err(e) => stopped = Some(e),
                        }
                    }
                    frames.push((i, Ok(waiting), ms + elapsed_ms(t0)));
                }
                Err(e) => frames.push((i, Err(e), ms)),
            }
        }
        let stop = stopped.is_some();
        let block = Filtered {
            frames,
            pieces,
            held_bytes: smoother.held_bytes(),
            refused: stopped,
            last: false,
        };
        if events.send(Event::Filtered(block)).is_err() || stop {
            return;
        }
    };
    let mut pieces = Vec::new();
    let mut refused = None;
    if let Some(step) = last {
        match smoother.push_step(step) {
            Ok(piece) => piece.into_iter().for_each(|p| cut(p, &mut pieces)),
            Err(e) => refused = Some(e),
        }
    }
    if refused.is_none() {
        match smoother.finish() {
            Ok(rest) => rest.into_iter().for_each(|p| cut(p, &mut pieces)),
            Err(e) => refused = Some(e),
        }
    }
    let _ = events.send(Event::Filtered(Filtered {
        frames: Vec::new(),
        pieces,
        held_bytes: 0,
        refused,
        last: true,
    }));
}
