//! The live Foxglove WebSocket server (`--serve ADDR`): the same messages
//! as the MCAP out, published as they are made. The `foxglove` crate runs
//! the server and its protocol on its own threads; a viewer that is slow
//! to read loses messages there (its per-client queue is bounded), never
//! the estimator's time.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};

use foxglove::{Context, PartialMetadata, RawChannel, Schema, WebSocketServer, WebSocketServerHandle};

use super::Outgoing;

/// The loopback address `--serve` takes when given none (Foxglove's own
/// default port).
pub const DEFAULT_SERVE_ADDR: &str = "127.0.0.1:8765";

/// How often the opening messages (the arm, the URDF) are sent again, so
/// that a viewer that connects later sees the arm.
const OPENING_EVERY: Duration = Duration::from_secs(1);

/// Why the server could not start or publish.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// The address is not `HOST:PORT`.
    #[error("--serve '{addr}': not an address (give HOST:PORT, e.g. {DEFAULT_SERVE_ADDR})")]
    Address {
        /// What was given.
        addr: String,
    },
    /// The server did not start (the port is taken, say).
    #[error("--serve {addr}: the Foxglove WebSocket server did not start: {reason}")]
    Start {
        /// Where.
        addr: String,
        /// Why.
        reason: String,
    },
    /// A channel could not be made.
    #[error("Foxglove server: topic {topic}: {reason}")]
    Channel {
        /// The topic.
        topic: String,
        /// Why.
        reason: String,
    },
}

/// A running Foxglove WebSocket server and its channels.
pub struct FoxgloveServer {
    context: Arc<Context>,
    handle: Option<WebSocketServerHandle>,
    address: SocketAddr,
    channels: HashMap<&'static str, Arc<RawChannel>>,
    opening: Vec<Outgoing>,
    opened: Option<Instant>,
}

impl std::fmt::Debug for FoxgloveServer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FoxgloveServer")
            .field("address", &self.address)
            .finish_non_exhaustive()
    }
}

impl FoxgloveServer {
    /// Starts a server on `addr` (`HOST:PORT`; port 0 picks a free one).
    pub fn start(addr: &str, name: &str) -> Result<Self, ServeError> {
        let parsed: SocketAddr = addr
            .parse()
            .map_err(|_| ServeError::Address { addr: addr.to_owned() })?;
        let context = Context::new();
        let handle = WebSocketServer::new()
            .name(name)
            .context(&context)
            .bind(parsed.ip().to_string(), parsed.port())
            .start_blocking()
            .map_err(|e| ServeError::Start {
                addr: addr.to_owned(),
                reason: e.to_string(),
            })?;
        let address = SocketAddr::new(parsed.ip(), handle.port());
        Ok(Self {
            context,
            handle: Some(handle),
            address,
            channels: HashMap::new(),
            opening: Vec::new(),
            opened: None,
        })
    }

    /// Where it listens (with the port it was given).
    #[must_use]
    pub fn address(&self) -> SocketAddr {
        self.address
    }

    /// How Foxglove opens it.
    #[must_use]
    pub fn open_hint(&self) -> String {
        format!("Foxglove: Open connection → Foxglove WebSocket → ws://{}", self.address)
    }

    /// Viewers connected now.
    #[must_use]
    pub fn clients(&self) -> usize {
        self.handle.as_ref().map_or(0, WebSocketServerHandle::client_count)
    }

    /// The messages a viewer needs whenever it joins (the arm, the URDF):
    /// sent now and again every second.
    pub fn set_opening(&mut self, opening: Vec<Outgoing>) -> Result<(), ServeError> {
        self.opening = opening;
        self.opened = None;
        self.send_opening_if_due()
    }

    fn send_opening_if_due(&mut self) -> Result<(), ServeError> {
        if self.opened.is_some_and(|t| t.elapsed() < OPENING_EVERY) {
            return Ok(());
        }
        self.opened = Some(Instant::now());
        let opening = std::mem::take(&mut self.opening);
        let sent = opening.iter().try_for_each(|m| self.send(m));
        self.opening = opening;
        sent
    }

    fn send(&mut self, message: &Outgoing) -> Result<(), ServeError> {
        let channel = if let Some(c) = self.channels.get(message.topic) {
            c.clone()
        } else {
            let schema = Schema::new(
                message.schema_name.clone(),
                message.schema_encoding,
                message.schema_data.clone(),
            );
            let c = self
                .context
                .channel_builder(message.topic)
                .message_encoding(message.message_encoding)
                .schema(schema)
                .build_raw()
                .map_err(|e| ServeError::Channel {
                    topic: message.topic.to_owned(),
                    reason: e.to_string(),
                })?;
            self.channels.insert(message.topic, c.clone());
            c
        };
        channel.log_with_meta(
            &message.data,
            PartialMetadata {
                log_time: u64::try_from(message.stamp_ns).ok(),
            },
        );
        Ok(())
    }

    /// Publishes messages (and the opening ones when they are due).
    pub fn publish(&mut self, messages: &[Outgoing]) -> Result<(), ServeError> {
        self.send_opening_if_due()?;
        messages.iter().try_for_each(|m| self.send(m))
    }
}

impl Drop for FoxgloveServer {
    fn drop(&mut self) {
        if let Some(handle) = self.handle.take() {
            handle.stop().wait_blocking();
        }
    }
}
