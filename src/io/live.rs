//! Live sources: frames in the session format arriving as JSON lines over
//! TCP (`host:port` or `tcp://host:port`: one sender at a time, each
//! connection starting afresh) or UDP (`udp://host:port`: each datagram
//! one or more lines), read on a thread of their own.
//!
//! A datagram's source address is its sender. UDP has no connections, so
//! the sender stands for one: the first sender's frames make a stream
//! segment, and a datagram from another sender starts a new segment (its
//! clock may start at 0 again) once the current sender has been quiet for
//! [`GAP_SECS`]. Two senders interleaving within that time are not one
//! stream: the other sender's datagrams are refused, with a message
//! naming both.

use std::io::{ErrorKind, Read as _};
use std::net::{TcpListener, TcpStream, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::time::{Duration, Instant};

use super::session::{Frame, LiveLine, LiveReader, MAX_LIVE_LINE_BYTES};

/// Why a live source could not start.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// The address could not be bound.
    #[error("{address}: cannot listen: {cause}")]
    Bind {
        /// The address as given.
        address: String,
        /// The system's reason.
        cause: std::io::Error,
    },
}

/// What a live source reports, in order.
#[derive(Debug, Clone, PartialEq)]
pub enum LiveEvent {
    /// A sender connected (TCP) or was first heard from (UDP).
    Connected(String),
    /// UDP: datagrams come from a new sender after the previous one went
    /// quiet: a new stream segment begins (nothing carries over).
    NewSender {
        /// The new sender's address.
        from: String,
        /// The sender before it.
        previous: String,
    },
    /// A header line: the robot and joint names it gives.
    Header {
        /// The robot named.
        robot: Option<String>,
        /// Joint names in column order (empty when not given).
        joints: Vec<String>,
    },
    /// A good frame.
    Frame(Frame),
    /// A line that was not used, and why (never fatal).
    Bad(String),
    /// Frames stopped for a while: the times around the gap, s.
    Gap {
        /// The last frame's time before it.
        from_t: f64,
        /// The next frame's time.
        to_t: f64,
    },
    /// The sender closed the connection, or the socket failed: why.
    Closed(String),
}

/// A pause between two frames of one sender longer than this, s, is
/// reported as a gap.
pub const GAP_SECS: f64 = 1.0;

/// Events a live source holds for its reader at most: when the reader
/// falls behind by this many, new frames are dropped (and counted,
/// [`LiveSource::dropped_frames`]) rather than queued, so that neither
/// the lag nor the memory grows without bound (a quarter of a second at
/// 1 kHz).
pub const QUEUE_EVENTS: usize = 256;

/// A listening live source; events arrive on [`LiveSource::events`].
pub struct LiveSource {
    /// The address listened on (with the port the system chose for port 0).
    pub address: String,
    /// The events, as they come.
    pub events: Receiver<LiveEvent>,
    /// Set when the source is dropped: its thread ends.
    stop: Arc<AtomicBool>,
    /// Frames dropped because the queue was full.
    dropped: Arc<AtomicU64>,
}

/// The reading thread's end of the queue: frames are dropped when it is
/// full, every other event waits for room.
struct Outbox {
    tx: SyncSender<LiveEvent>,
    dropped: Arc<AtomicU64>,
}

/// The reader is gone.
struct Gone;

impl Outbox {
    fn send(&self, event: LiveEvent) -> Result<(), Gone> {
        if !matches!(event, LiveEvent::Frame(_)) {
            return self.tx.send(event).map_err(|_| Gone);
        }
        match self.tx.try_send(event) {
            Ok(()) => Ok(()),
            Err(TrySendError::Full(_)) => {
                self.dropped.fetch_add(1, Ordering::Relaxed);
                Ok(())
            }
            Err(TrySendError::Disconnected(_)) => Err(Gone),
        }
    }
}

/// The transport and socket address of `address`.
fn parse(address: &str) -> (bool, &str) {
    if let Some(rest) = address.strip_prefix("udp://") {
        (true, rest)
    } else {
        (false, address.strip_prefix("tcp://").unwrap_or(address))
    }
}

impl LiveSource {
    /// Listens on `address` (see the module's doc); `wake` is called after
    /// each batch of events (e.g. to repaint a window).
    pub fn listen(address: &str, wake: impl Fn() + Send + 'static) -> Result<Self, LiveError> {
        let (udp, socket_address) = parse(address);
        let bind_error = |cause| LiveError::Bind {
            address: address.to_owned(),
            cause,
        };
        let (tx, events) = sync_channel(QUEUE_EVENTS);
        let dropped = Arc::new(AtomicU64::new(0));
        let tx = Outbox {
            tx,
            dropped: Arc::clone(&dropped),
        };
        let stop = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&stop);
        let bound = if udp {
            let socket = UdpSocket::bind(socket_address).map_err(bind_error)?;
            let local = socket.local_addr().map_err(bind_error)?;
            std::thread::spawn(move || receive_udp(&socket, &tx, &wake, &flag));
            format!("udp://{local}")
        } else {
            let listener = TcpListener::bind(socket_address).map_err(bind_error)?;
            let local = listener.local_addr().map_err(bind_error)?;
            std::thread::spawn(move || accept_tcp(&listener, &tx, &wake, &flag));
            local.to_string()
        };
        Ok(Self {
            address: bound,
            events,
            stop,
            dropped,
        })
    }

    /// Frames dropped so far because the reader fell behind by
    /// [`QUEUE_EVENTS`].
    #[must_use]
    pub fn dropped_frames(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

impl Drop for LiveSource {
    /// The thread ends within `POLL` and frees the address.
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

/// Sends what a line gives (a gap first when the frame comes after one);
/// `false` when nobody listens any more.
fn send_line(tx: &Outbox, reader: &mut LiveReader, last_t: &mut Option<f64>, line: &str, from: &str) -> bool {
    let event = event(reader, line, from);
    if let LiveEvent::Frame(frame) = &event {
        if let Some(t) = *last_t
            && frame.t - t > GAP_SECS
            && tx
                .send(LiveEvent::Gap {
                    from_t: t,
                    to_t: frame.t,
                })
                .is_err()
        {
            return false;
        }
        *last_t = Some(frame.t);
    }
    tx.send(event).is_ok()
}

/// What a line gives, as an event.
fn event(reader: &mut LiveReader, line: &str, from: &str) -> LiveEvent {
    match reader.line(line) {
        LiveLine::Header { robot, joints } => LiveEvent::Header { robot, joints },
        LiveLine::Frame(frame) => LiveEvent::Frame(frame),
        LiveLine::Bad(p) => LiveEvent::Bad(format!(
            "{from}: skipped line {} (counting from 0): {}: {}",
            p.frame, p.field, p.message
        )),
    }
}

/// How often a waiting thread looks whether it should stop.
const POLL: Duration = Duration::from_millis(100);

/// Whether `e` only says that nothing came in time.
fn timed_out(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
    )
}

fn accept_tcp(listener: &TcpListener, tx: &Outbox, wake: &dyn Fn(), stop: &AtomicBool) {
    // Polled, so that a dropped source frees its port.
    if let Err(e) = listener.set_nonblocking(true) {
        let _ = tx.send(LiveEvent::Closed(e.to_string()));
        return;
    }
    let mut reader = LiveReader::new(None);
    while !stop.load(Ordering::Relaxed) {
        let (connection, from) = match listener.accept() {
            Ok(accepted) => accepted,
            Err(e) if timed_out(&e) => {
                std::thread::sleep(POLL);
                continue;
            }
            Err(_) => continue,
        };
        let from = from.to_string();
        reader.restart();
        if tx.send(LiveEvent::Connected(from.clone())).is_err() {
            return;
        }
        wake();
        let Some(why) = read_connection(&connection, &from, &mut reader, tx, wake, stop) else {
            return;
        };
        if tx.send(LiveEvent::Closed(why)).is_err() {
            return;
        }
        wake();
    }
}

/// Reads one connection's lines until it closes (why), or `None` when the
/// source stops or nobody listens any more. A line longer than
/// [`MAX_LIVE_LINE_BYTES`] is reported once and skipped to its end.
fn read_connection(
    connection: &TcpStream,
    from: &str,
    reader: &mut LiveReader,
    tx: &Outbox,
    wake: &dyn Fn(),
    stop: &AtomicBool,
) -> Option<String> {
    if let Err(e) = connection
        .set_nonblocking(false)
        .and_then(|()| connection.set_read_timeout(Some(POLL)))
    {
        return Some(format!("{from}: {e}"));
    }
    let mut pending: Vec<u8> = Vec::new();
    let mut skipping = false;
    let mut chunk = [0u8; 8192];
    let mut last_t = None;
    loop {
        if stop.load(Ordering::Relaxed) {
            return None;
        }
        match (&*connection).read(&mut chunk) {
            Ok(0) => return Some(format!("{from}: closed")),
            Ok(n) => pending.extend_from_slice(chunk.get(..n).unwrap_or_default()),
            Err(e) if timed_out(&e) => continue,
            Err(e) => return Some(format!("{from}: {e}")),
        }
        while let Some(end) = pending.iter().position(|&b| b == b'\n') {
            let line: Vec<u8> = pending.drain(..=end).collect();
            if std::mem::take(&mut skipping) {
                continue;
            }
            let text = String::from_utf8_lossy(&line);
            if !send_line(tx, reader, &mut last_t, text.trim_end(), from) {
                return None;
            }
        }
        if skipping {
            pending.clear();
        } else if pending.len() > MAX_LIVE_LINE_BYTES {
            let text = String::from_utf8_lossy(&pending);
            if !send_line(tx, reader, &mut last_t, &text, from) {
                return None;
            }
            pending.clear();
            skipping = true;
        }
        wake();
    }
}

fn receive_udp(socket: &UdpSocket, tx: &Outbox, wake: &dyn Fn(), stop: &AtomicBool) {
    if let Err(e) = socket.set_read_timeout(Some(POLL)) {
        let _ = tx.send(LiveEvent::Closed(e.to_string()));
        return;
    }
    let mut reader = LiveReader::new(None);
    let mut buffer = vec![0u8; 65_536];
    let mut senders = Senders::default();
    let mut last_t = None;
    while !stop.load(Ordering::Relaxed) {
        let (n, from) = match socket.recv_from(&mut buffer) {
            Ok(got) => got,
            Err(e) if timed_out(&e) => continue,
            Err(e) => {
                let _ = tx.send(LiveEvent::Closed(e.to_string()));
                wake();
                return;
            }
        };
        let from = from.to_string();
        let event = match senders.heard(&from, Instant::now()) {
            Heard::Current => None,
            Heard::First => Some(LiveEvent::Connected(from.clone())),
            Heard::Next { previous } => Some(LiveEvent::NewSender {
                from: from.clone(),
                previous,
            }),
            Heard::Interleaving { current, report } => {
                if let Some(refused) = report {
                    let message = format!(
                        "udp: refused {refused} datagram{} from {from}: {current} is sending, and two senders interleaving are not one stream (stop one, or send to another port; a new sender is taken once the current one has been quiet for {GAP_SECS} s)",
                        if refused == 1 { "" } else { "s" }
                    );
                    if tx.send(LiveEvent::Bad(message)).is_err() {
                        return;
                    }
                    wake();
                }
                continue;
            }
        };
        if let Some(event) = event {
            // A new segment: its clock starts afresh.
            reader.restart();
            last_t = None;
            if tx.send(event).is_err() {
                return;
            }
        }
        let text = String::from_utf8_lossy(buffer.get(..n).unwrap_or_default());
        for line in text.lines().filter(|l| !l.trim().is_empty()) {
            if !send_line(tx, &mut reader, &mut last_t, line.trim_end(), &from) {
                return;
            }
        }
        wake();
    }
}

/// Who sends to a UDP source: the current sender, when it was last heard,
/// and the datagrams refused from others since the last report.
#[derive(Debug, Default)]
struct Senders {
    current: Option<(String, Instant)>,
    refused: usize,
    reported: Option<Instant>,
}

/// What a datagram's sender is to the stream.
#[derive(Debug, PartialEq)]
enum Heard {
    /// The sender of the segment going on.
    Current,
    /// The first sender heard.
    First,
    /// A new sender after the previous went quiet: a new segment.
    Next { previous: String },
    /// Another sender while the current one sends: refused; `report`
    /// carries how many were refused since the last report, at most once
    /// a second.
    Interleaving { current: String, report: Option<usize> },
}

impl Senders {
    /// A datagram from `from` at `now`.
    fn heard(&mut self, from: &str, now: Instant) -> Heard {
        let quiet = Duration::from_secs_f64(GAP_SECS);
        let heard = match &mut self.current {
            Some((current, last)) if current == from => {
                *last = now;
                return Heard::Current;
            }
            Some((current, last)) if now.saturating_duration_since(*last) < quiet => {
                self.refused += 1;
                let due = self
                    .reported
                    .is_none_or(|at| now.saturating_duration_since(at) >= Duration::from_secs(1));
                let report = due.then(|| {
                    self.reported = Some(now);
                    std::mem::take(&mut self.refused)
                });
                return Heard::Interleaving {
                    current: current.clone(),
                    report,
                };
            }
            Some((current, _)) => Heard::Next {
                previous: current.clone(),
            },
            None => Heard::First,
        };
        self.current = Some((from.to_owned(), now));
        self.refused = 0;
        self.reported = None;
        heard
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write as _;
    use std::time::Duration;

    fn collect(source: &LiveSource, frames: usize) -> Vec<LiveEvent> {
        let mut got = Vec::new();
        while got.iter().filter(|e| matches!(e, LiveEvent::Frame(_))).count() < frames {
            got.push(source.events.recv_timeout(Duration::from_secs(10)).unwrap());
        }
        got
    }

    const LINES: &str = "{\"format\": \"contact-session\", \"version\": 1, \"robot\": \"lwr4plus\"}\n\
{\"t\": 0.0, \"q\": [0, 0], \"tau\": [0.5, 0]}\nnot json\n{\"t\": 0.1, \"q\": [0, 1], \"tau\": [0, 0]}\n";

    /// A reader that falls behind gets at most the queue's worth of
    /// events; the other frames are dropped and counted, none lost
    /// unaccounted.
    #[test]
    fn frames_beyond_the_queue_are_dropped_and_counted() {
        use std::fmt::Write as _;
        let source = LiveSource::listen("127.0.0.1:0", || {}).unwrap();
        let mut c = std::net::TcpStream::connect(&source.address).unwrap();
        let sent = 3000;
        let mut text = String::from("{\"format\": \"contact-session\", \"version\": 1}\n");
        for i in 0..sent {
            writeln!(
                text,
                "{{\"t\": {}, \"q\": [0, 0], \"tau\": [0, 0]}}",
                f64::from(i) * 1e-3
            )
            .unwrap();
        }
        c.write_all(text.as_bytes()).unwrap();
        drop(c);
        // Nothing is read until the sender has closed.
        let mut events = Vec::new();
        loop {
            let event = source.events.recv_timeout(Duration::from_secs(10)).unwrap();
            let closed = matches!(event, LiveEvent::Closed(_));
            events.push(event);
            if closed {
                break;
            }
            if events.len() == 1 {
                std::thread::sleep(Duration::from_millis(500));
            }
        }
        let frames = events.iter().filter(|e| matches!(e, LiveEvent::Frame(_))).count();
        let dropped = source.dropped_frames();
        assert!(frames <= QUEUE_EVENTS + 2, "{frames} frames queued");
        assert!(dropped > 0);
        assert_eq!(frames as u64 + dropped, sent as u64);
    }

    #[test]
    fn a_pause_between_frames_is_reported_as_a_gap() {
        let source = LiveSource::listen("127.0.0.1:0", || {}).unwrap();
        let mut c = std::net::TcpStream::connect(&source.address).unwrap();
        let text = LINES.replace("\"t\": 0.1", "\"t\": 2.5");
        c.write_all(text.as_bytes()).unwrap();
        let events = collect(&source, 2);
        assert!(
            events.contains(&LiveEvent::Gap { from_t: 0.0, to_t: 2.5 }),
            "{events:?}"
        );
    }

    #[test]
    fn tcp_lines_become_events_and_a_reconnect_starts_afresh() {
        let source = LiveSource::listen("127.0.0.1:0", || {}).unwrap();
        for _ in 0..2 {
            let mut c = std::net::TcpStream::connect(&source.address).unwrap();
            c.write_all(LINES.as_bytes()).unwrap();
            drop(c);
            let events = collect(&source, 2);
            assert!(matches!(events[0], LiveEvent::Connected(_)));
            assert_eq!(
                events[1],
                LiveEvent::Header {
                    robot: Some("lwr4plus".into()),
                    joints: Vec::new()
                }
            );
            assert!(matches!(&events[2], LiveEvent::Frame(f) if f.tau == [0.5, 0.0]));
            assert!(
                matches!(&events[3], LiveEvent::Bad(why) if why.contains("skipped line")),
                "{:?}",
                events[3]
            );
            assert!(matches!(&events[4], LiveEvent::Frame(f) if (f.t - 0.1).abs() < 1e-12));
            assert!(matches!(
                source.events.recv_timeout(Duration::from_secs(10)),
                Ok(LiveEvent::Closed(_))
            ));
        }
    }

    #[test]
    fn a_dropped_source_frees_its_address() {
        let source = LiveSource::listen("127.0.0.1:0", || {}).unwrap();
        let address = source.address.clone();
        drop(source);
        std::thread::sleep(POLL * 3);
        assert!(LiveSource::listen(&address, || {}).is_ok(), "{address} still taken");
    }

    #[test]
    fn an_overlong_line_is_reported_once_and_the_next_line_read() {
        let source = LiveSource::listen("127.0.0.1:0", || {}).unwrap();
        let mut c = std::net::TcpStream::connect(&source.address).unwrap();
        let long = "x".repeat(MAX_LIVE_LINE_BYTES + 10_000);
        c.write_all(format!("{long}\n{{\"t\": 0.0, \"q\": [0], \"tau\": [1]}}\n").as_bytes())
            .unwrap();
        let events = collect(&source, 1);
        let bad = events.iter().filter(|e| matches!(e, LiveEvent::Bad(_))).count();
        assert_eq!(
            bad,
            1,
            "{:?}",
            events
                .iter()
                .map(|e| format!("{e:?}").chars().take(80).collect::<String>())
                .collect::<Vec<_>>()
        );
    }

    #[test]
    fn udp_datagrams_carry_lines() {
        let source = LiveSource::listen("udp://127.0.0.1:0", || {}).unwrap();
        let to = source.address.trim_start_matches("udp://").to_owned();
        let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
        let (head, rest) = LINES.split_once('\n').unwrap();
        socket.send_to(head.as_bytes(), &to).unwrap();
        std::thread::sleep(Duration::from_millis(50));
        socket.send_to(rest.as_bytes(), &to).unwrap();
        let events = collect(&source, 2);
        assert!(matches!(events[0], LiveEvent::Connected(_)));
        assert!(matches!(events[1], LiveEvent::Header { .. }));
        let frames: Vec<f64> = events
            .iter()
            .filter_map(|e| match e {
                LiveEvent::Frame(f) => Some(f.t),
                _ => None,
            })
            .collect();
        assert_eq!(frames, [0.0, 0.1]);
    }

    #[test]
    fn senders_take_turns_and_interleaving_is_refused_naming_both() {
        let mut senders = Senders::default();
        let t0 = Instant::now();
        let at = |ms: u64| t0 + Duration::from_millis(ms);
        assert_eq!(senders.heard("a:1", at(0)), Heard::First);
        assert_eq!(senders.heard("a:1", at(10)), Heard::Current);
        // b while a sends: refused, reported once a second with a count.
        assert_eq!(
            senders.heard("b:2", at(20)),
            Heard::Interleaving {
                current: "a:1".into(),
                report: Some(1)
            }
        );
        assert_eq!(senders.heard("a:1", at(30)), Heard::Current);
        for ms in [40, 50, 60] {
            assert!(matches!(
                senders.heard("b:2", at(ms)),
                Heard::Interleaving { report: None, .. }
            ));
        }
        assert_eq!(senders.heard("a:1", at(900)), Heard::Current);
        assert_eq!(
            senders.heard("b:2", at(1100)),
            Heard::Interleaving {
                current: "a:1".into(),
                report: Some(4)
            }
        );
        // a goes quiet for a gap: b takes over as a new segment.
        assert_eq!(
            senders.heard("b:2", at(1900 + 1000)),
            Heard::Next { previous: "a:1".into() }
        );
        assert_eq!(senders.heard("b:2", at(2950)), Heard::Current);
    }

    /// A frame line at time `t`.
    fn frame_line(t: f64) -> String {
        format!("{{\"t\": {t}, \"q\": [0, 0], \"tau\": [0.5, 0]}}")
    }

    #[test]
    fn a_second_udp_sender_starts_a_new_segment_whose_clock_starts_again() {
        let source = LiveSource::listen("udp://127.0.0.1:0", || {}).unwrap();
        let to = source.address.trim_start_matches("udp://").to_owned();
        let first = UdpSocket::bind("127.0.0.1:0").unwrap();
        for k in 0..3 {
            first.send_to(frame_line(5.0 + f64::from(k)).as_bytes(), &to).unwrap();
        }
        let events = collect(&source, 3);
        assert!(matches!(events[0], LiveEvent::Connected(_)), "{events:?}");
        // The first sender stops; a restarted sender (another port) counts from 0.
        std::thread::sleep(Duration::from_secs_f64(GAP_SECS + 0.2));
        let second = UdpSocket::bind("127.0.0.1:0").unwrap();
        for k in 0..3 {
            second.send_to(frame_line(f64::from(k)).as_bytes(), &to).unwrap();
            std::thread::sleep(Duration::from_millis(10));
        }
        let events = collect(&source, 3);
        let from = second.local_addr().unwrap().to_string();
        let previous = first.local_addr().unwrap().to_string();
        assert_eq!(events[0], LiveEvent::NewSender { from, previous }, "{events:?}");
        let times: Vec<f64> = events
            .iter()
            .filter_map(|e| match e {
                LiveEvent::Frame(f) => Some(f.t),
                _ => None,
            })
            .collect();
        assert_eq!(times, [0.0, 1.0, 2.0], "{events:?}");
        assert!(!events.iter().any(|e| matches!(e, LiveEvent::Bad(_))), "{events:?}");
    }

    #[test]
    fn two_udp_senders_interleaving_are_refused_with_both_named() {
        let source = LiveSource::listen("udp://127.0.0.1:0", || {}).unwrap();
        let to = source.address.trim_start_matches("udp://").to_owned();
        let (a, b) = (
            UdpSocket::bind("127.0.0.1:0").unwrap(),
            UdpSocket::bind("127.0.0.1:0").unwrap(),
        );
        for k in 0..4 {
            a.send_to(frame_line(10.0 + f64::from(k)).as_bytes(), &to).unwrap();
            std::thread::sleep(Duration::from_millis(5));
            b.send_to(frame_line(f64::from(k)).as_bytes(), &to).unwrap();
            std::thread::sleep(Duration::from_millis(5));
        }
        let events = collect(&source, 4);
        let times: Vec<f64> = events
            .iter()
            .filter_map(|e| match e {
                LiveEvent::Frame(f) => Some(f.t),
                _ => None,
            })
            .collect();
        assert_eq!(times, [10.0, 11.0, 12.0, 13.0], "only the first sender's frames");
        let (a, b) = (a.local_addr().unwrap().to_string(), b.local_addr().unwrap().to_string());
        let refusal = events
            .iter()
            .find_map(|e| match e {
                LiveEvent::Bad(why) => Some(why.clone()),
                _ => None,
            })
            .unwrap();
        assert!(refusal.contains(&a) && refusal.contains(&b), "{refusal}");
        assert!(!events.iter().any(|e| matches!(e, LiveEvent::NewSender { .. })));
    }
}
