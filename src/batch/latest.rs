//! The worker mechanisms, written once: [`Latest`], a thread that serves
//! the newest request (requests that arrive while one is served supersede
//! each other; the serving function may send several results and look
//! for a newer request between them, and stop), on which the app's
//! estimator and the background estimation of sessions run; and
//! [`Background`], one job on a thread of its own (opening a scene, a
//! robot, a session). Both are supervised: a panic is an error result,
//! never a thread that silently stops.

use std::cell::{Cell, RefCell};
use std::sync::mpsc::{Receiver, Sender, TryIter, TryRecvError, channel};
use std::time::{Duration, Instant};

/// Handle to a thread serving the newest of its requests.
pub struct Latest<R, O> {
    requests: Sender<R>,
    results: Receiver<O>,
}

/// What the serving function sees of its thread while it serves one
/// request.
pub struct Serving<'a, R, O> {
    inbox: &'a Receiver<R>,
    outbox: &'a Sender<O>,
    wake: &'a dyn Fn(),
    newer: RefCell<Option<R>>,
    gone: Cell<bool>,
    last_wake: Cell<Option<Instant>>,
}

/// The receiver is woken at most this often while results stream in.
const WAKE_EVERY: Duration = Duration::from_millis(100);

impl<R, O> Serving<'_, R, O> {
    /// Sends a result; false once nobody listens any more.
    pub fn send(&self, result: O) -> bool {
        if self.outbox.send(result).is_err() {
            self.gone.set(true);
        }
        !self.gone.get()
    }

    /// Whether to stop: a newer request arrived (it is served next), or
    /// nobody listens.
    pub fn should_stop(&self) -> bool {
        if let Some(request) = self.inbox.try_iter().last() {
            *self.newer.borrow_mut() = Some(request);
        }
        self.newer.borrow().is_some() || self.gone.get()
    }

    /// Wakes the receiver, at most ten times a second.
    pub fn wake_now_and_then(&self) {
        if self.last_wake.get().is_none_or(|at| at.elapsed() >= WAKE_EVERY) {
            (self.wake)();
            self.last_wake.set(Some(Instant::now()));
        }
    }
}

impl<R: Send + 'static, O: Send + 'static> Latest<R, O> {
    /// Starts the thread: `serve` answers each request through its
    /// [`Serving`]; `wake` is called after each request served (to
    /// repaint a window, say).
    pub fn spawn<S>(wake: impl Fn() + Send + 'static, serve: S) -> Self
    where
        S: FnMut(R, &Serving<'_, R, O>) + Send + 'static,
    {
        let (requests, inbox) = channel::<R>();
        let (outbox, results) = channel::<O>();
        std::thread::spawn(move || {
            let mut serve = serve;
            let mut next: Option<R> = None;
            loop {
                let mut request = match next.take() {
                    Some(r) => r,
                    None => match inbox.recv() {
                        Ok(r) => r,
                        Err(_) => return,
                    },
                };
                // Only the newest request matters.
                while let Ok(newer) = inbox.try_recv() {
                    request = newer;
                }
                let serving = Serving {
                    inbox: &inbox,
                    outbox: &outbox,
                    wake: &wake,
                    newer: RefCell::new(None),
                    gone: Cell::new(false),
                    last_wake: Cell::new(None),
                };
                serve(request, &serving);
                if serving.gone.get() {
                    return;
                }
                next = serving.newer.into_inner();
                wake();
            }
        });
        Self { requests, results }
    }

    /// Queues a request (it supersedes any still waiting, and tells the
    /// one being served to stop where it looks).
    pub fn request(&self, request: R) {
        let _ = self.requests.send(request);
    }

    /// The results that have arrived since the last call.
    #[must_use]
    pub fn results(&self) -> TryIter<'_, O> {
        self.results.try_iter()
    }
}

/// One job on a thread of its own, supervised (a panic is its error),
/// polled by the caller: how scenes, robots and sessions are opened
/// without freezing the window.
pub struct Background<T, E = String> {
    result: Receiver<Result<T, E>>,
    /// What is being done, for the status line.
    pub what: String,
}

impl<T: Send + 'static, E: From<String> + Send + 'static> Background<T, E> {
    /// Starts `job`; `wake` is called when it is done.
    pub fn spawn(
        what: String,
        job: impl FnOnce() -> Result<T, E> + Send + 'static,
        wake: impl Fn() + Send + 'static,
    ) -> Self {
        let (tx, result) = channel();
        std::thread::spawn(move || {
            let done = crate::io::guard::isolated(job).unwrap_or_else(|panic| Err(E::from(panic)));
            let _ = tx.send(done);
            wake();
        });
        Self { result, what }
    }

    /// The result, once it is there.
    #[must_use]
    pub fn poll(&self) -> Option<Result<T, E>> {
        match self.result.try_recv() {
            Ok(r) => Some(r),
            Err(TryRecvError::Empty) => None,
            Err(TryRecvError::Disconnected) => Some(Err(E::from("the thread stopped".to_owned()))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A request that arrives while one is served stops it where it looks,
    /// and is served next; requests queued together collapse into the
    /// newest.
    #[test]
    fn the_newest_request_wins() {
        let (gate_tx, gate) = std::sync::mpsc::channel::<()>();
        let gate = std::sync::Mutex::new(gate);
        let worker: Latest<u32, (u32, u32)> = Latest::spawn(
            || {},
            move |n, serving| {
                for step in 0..100 {
                    if n == 1 && step == 1 {
                        // Wait until the test has queued newer requests.
                        let _ = gate.lock().map(|g| g.recv());
                    }
                    if serving.should_stop() {
                        return;
                    }
                    serving.send((n, step));
                }
            },
        );
        worker.request(1);
        std::thread::sleep(Duration::from_millis(50));
        worker.request(2);
        worker.request(3);
        gate_tx.send(()).unwrap();
        let mut got = Vec::new();
        let started = Instant::now();
        while got.last() != Some(&(3, 99)) && started.elapsed() < Duration::from_secs(10) {
            got.extend(worker.results());
            std::thread::sleep(Duration::from_millis(5));
        }
        assert_eq!(got.first(), Some(&(1, 0)));
        assert!(got.iter().all(|(n, _)| *n != 2), "request 2 was superseded by 3");
        assert!(got.iter().filter(|(n, _)| *n == 1).count() <= 2, "request 1 stopped");
        assert_eq!(got.iter().filter(|(n, _)| *n == 3).count(), 100);
    }

    /// A job that panics reports the panic as its error.
    #[test]
    fn a_panicking_job_is_an_error() {
        let job: Background<u32> = Background::spawn("x".to_owned(), || panic!("boom"), || {});
        let started = Instant::now();
        let result = loop {
            if let Some(r) = job.poll() {
                break r;
            }
            assert!(started.elapsed() < Duration::from_secs(10));
            std::thread::sleep(Duration::from_millis(5));
        };
        assert!(result.is_err_and(|e| e.contains("boom")));
    }
}
