//! A small, blocking client of Foxglove's WebSocket protocol, written from its specification
//! (github.com/foxglove/ws-protocol, `docs/spec.md`) rather than with the `foxglove` crate's
//! own types, so that a test with it checks the server from outside: the tests and the
//! `watch` example use it.
//!
//! What it speaks: the subprotocol [`SUBPROTOCOL`]; the server's `serverInfo` and `advertise`
//! (JSON text frames); `subscribe` (a text frame it sends); message data (binary frames: opcode
//! 1, subscription id u32 LE, log time u64 LE, the message).

use std::collections::HashMap;
use std::io::ErrorKind;
use std::net::{SocketAddr, TcpStream};
use std::time::{Duration, Instant};

use serde_json::Value;
use tungstenite::client::IntoClientRequest;
use tungstenite::http::HeaderValue;
use tungstenite::{Message, WebSocket};

/// The subprotocol the `foxglove` crate's server speaks (0.30: `foxglove.sdk.v1`; it refuses
/// the former name `foxglove.websocket.v1`).
pub const SUBPROTOCOL: &str = "foxglove.sdk.v1";
/// The binary opcode of message data.
pub const MESSAGE_DATA: u8 = 1;

/// What went wrong talking to the server.
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    #[error("connecting to {addr}: {source}")]
    Connect {
        addr: SocketAddr,
        #[source]
        source: std::io::Error,
    },
    #[error("WebSocket: {0}")]
    WebSocket(#[from] tungstenite::Error),
    #[error("WebSocket handshake: {0}")]
    Handshake(String),
    /// The server said something the protocol does not allow (or not in time).
    #[error("protocol: {0}")]
    Protocol(String),
}

/// A channel the server advertised.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Advertised {
    pub id: u64,
    pub topic: String,
    /// Message encoding, e.g. `json`.
    pub encoding: String,
    pub schema_name: String,
    /// e.g. `jsonschema`.
    pub schema_encoding: String,
    /// The schema as sent (text for `jsonschema`).
    pub schema: String,
}

/// One message the server sent for a subscription.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Received {
    /// The channel's topic.
    pub topic: String,
    /// Log time, Unix nanoseconds.
    pub log_time_ns: u64,
    /// The message as published.
    pub data: Vec<u8>,
}

/// A connection to a live view.
pub struct WatchClient {
    socket: WebSocket<TcpStream>,
    /// The server's name (`serverInfo`).
    pub server_name: String,
    channels: Vec<Advertised>,
    /// Subscription id to channel id.
    subscriptions: HashMap<u32, u64>,
    /// Messages read while waiting for something else.
    pending: Vec<Received>,
}

fn text(value: &Value, field: &str) -> String {
    value[field].as_str().unwrap_or_default().to_owned()
}

impl WatchClient {
    /// Connects, offering [`SUBPROTOCOL`] (or `subprotocol`), and reads `serverInfo`; within
    /// `timeout`.
    pub fn connect(addr: SocketAddr, timeout: Duration) -> Result<Self, ClientError> {
        Self::connect_as(addr, SUBPROTOCOL, timeout)
    }

    /// [`WatchClient::connect`] offering `subprotocol`.
    pub fn connect_as(addr: SocketAddr, subprotocol: &str, timeout: Duration) -> Result<Self, ClientError> {
        let stream =
            TcpStream::connect_timeout(&addr, timeout).map_err(|source| ClientError::Connect { addr, source })?;
        stream
            .set_read_timeout(Some(timeout))
            .map_err(|source| ClientError::Connect { addr, source })?;
        let mut request = format!("ws://{addr}/").into_client_request()?;
        let offered = HeaderValue::from_str(subprotocol).map_err(|e| ClientError::Handshake(e.to_string()))?;
        request.headers_mut().insert("sec-websocket-protocol", offered);
        let (socket, response) =
            tungstenite::client(request, stream).map_err(|e| ClientError::Handshake(e.to_string()))?;
        let agreed = response.headers().get("sec-websocket-protocol");
        if agreed.and_then(|v| v.to_str().ok()) != Some(subprotocol) {
            return Err(ClientError::Handshake(format!("the server agreed to {agreed:?}")));
        }
        let mut client = Self {
            socket,
            server_name: String::new(),
            channels: Vec::new(),
            subscriptions: HashMap::new(),
            pending: Vec::new(),
        };
        let deadline = Instant::now() + timeout;
        loop {
            match client.read_json(deadline)? {
                Some(info) if info["op"] == "serverInfo" => {
                    client.server_name = text(&info, "name");
                    return Ok(client);
                }
                Some(other) => client.take_json(&other)?,
                None => return Err(ClientError::Protocol("no serverInfo".into())),
            }
        }
    }

    /// The channels advertised so far.
    pub fn channels(&self) -> &[Advertised] {
        &self.channels
    }

    /// Waits (until `deadline`) for the first advertisement, if none came yet; the channels
    /// advertised.
    pub fn wait_for_channels(&mut self, deadline: Instant) -> Result<&[Advertised], ClientError> {
        while self.channels.is_empty() {
            match self.read_json(deadline)? {
                Some(message) => self.take_json(&message)?,
                None => return Err(ClientError::Protocol("no channel advertised".into())),
            }
        }
        Ok(&self.channels)
    }

    /// Waits (until `deadline`) for the advertisement of `topic`.
    pub fn wait_for_channel(&mut self, topic: &str, deadline: Instant) -> Result<Advertised, ClientError> {
        loop {
            if let Some(c) = self.channels.iter().find(|c| c.topic == topic) {
                return Ok(c.clone());
            }
            match self.read_json(deadline)? {
                Some(message) => self.take_json(&message)?,
                None => return Err(ClientError::Protocol(format!("`{topic}` never advertised"))),
            }
        }
    }

    /// Subscribes to `topics` (waiting for their advertisements until `deadline`).
    pub fn subscribe(&mut self, topics: &[&str], deadline: Instant) -> Result<(), ClientError> {
        let mut subscriptions = Vec::new();
        for topic in topics {
            let channel = self.wait_for_channel(topic, deadline)?;
            let id = u32::try_from(self.subscriptions.len() + 1).unwrap_or(u32::MAX);
            self.subscriptions.insert(id, channel.id);
            subscriptions.push(serde_json::json!({ "id": id, "channelId": channel.id }));
        }
        let message = serde_json::json!({ "op": "subscribe", "subscriptions": subscriptions });
        self.socket.send(Message::text(message.to_string()))?;
        Ok(())
    }

    /// The next message of a subscription, or `None` if none came by `deadline`. Text
    /// frames that arrive meanwhile (more advertisements, status) are taken in.
    pub fn next_message(&mut self, deadline: Instant) -> Result<Option<Received>, ClientError> {
        if !self.pending.is_empty() {
            return Ok(Some(self.pending.remove(0)));
        }
        loop {
            match self.read(deadline)? {
                None => return Ok(None),
                Some(Message::Binary(frame)) => return self.message_data(&frame).map(Some),
                Some(Message::Text(t)) => {
                    let value: Value = serde_json::from_str(&t).map_err(|e| ClientError::Protocol(e.to_string()))?;
                    self.take_json(&value)?;
                }
                Some(Message::Close(frame)) => {
                    return Err(ClientError::Protocol(format!("the server closed: {frame:?}")));
                }
                Some(_) => {}
            }
        }
    }

    /// A message data frame.
    fn message_data(&self, frame: &[u8]) -> Result<Received, ClientError> {
        let bad = |what: &str| ClientError::Protocol(format!("binary frame: {what}"));
        let (&opcode, rest) = frame.split_first().ok_or_else(|| bad("empty"))?;
        if opcode != MESSAGE_DATA {
            return Err(bad(&format!("opcode {opcode}, expected {MESSAGE_DATA}")));
        }
        if rest.len() < 12 {
            return Err(bad("shorter than its header"));
        }
        let subscription = u32::from_le_bytes(rest[..4].try_into().expect("4 bytes"));
        let log_time_ns = u64::from_le_bytes(rest[4..12].try_into().expect("8 bytes"));
        let channel = self
            .subscriptions
            .get(&subscription)
            .ok_or_else(|| bad(&format!("unknown subscription {subscription}")))?;
        let topic = self
            .channels
            .iter()
            .find(|c| c.id == *channel)
            .map(|c| c.topic.clone())
            .ok_or_else(|| bad(&format!("channel {channel} not advertised")))?;
        Ok(Received {
            topic,
            log_time_ns,
            data: rest[12..].to_vec(),
        })
    }

    /// Takes in a JSON message of the server: advertisements are kept, the rest ignored.
    fn take_json(&mut self, message: &Value) -> Result<(), ClientError> {
        match message["op"].as_str() {
            Some("advertise") => {
                let channels = message["channels"]
                    .as_array()
                    .ok_or_else(|| ClientError::Protocol(format!("advertise without channels: {message}")))?;
                for c in channels {
                    let id = c["id"]
                        .as_u64()
                        .ok_or_else(|| ClientError::Protocol(format!("channel without id: {c}")))?;
                    self.channels.retain(|known| known.id != id);
                    self.channels.push(Advertised {
                        id,
                        topic: text(c, "topic"),
                        encoding: text(c, "encoding"),
                        schema_name: text(c, "schemaName"),
                        schema_encoding: text(c, "schemaEncoding"),
                        schema: text(c, "schema"),
                    });
                }
            }
            Some("unadvertise") => {
                if let Some(ids) = message["channelIds"].as_array() {
                    self.channels
                        .retain(|c| !ids.iter().any(|id| id.as_u64() == Some(c.id)));
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// The next JSON text frame (binary frames meanwhile are kept for [`Self::next_message`]).
    fn read_json(&mut self, deadline: Instant) -> Result<Option<Value>, ClientError> {
        loop {
            match self.read(deadline)? {
                None => return Ok(None),
                Some(Message::Text(t)) => {
                    return serde_json::from_str(&t)
                        .map(Some)
                        .map_err(|e| ClientError::Protocol(e.to_string()));
                }
                Some(Message::Binary(frame)) => {
                    let message = self.message_data(&frame)?;
                    self.pending.push(message);
                }
                Some(Message::Close(frame)) => {
                    return Err(ClientError::Protocol(format!("the server closed: {frame:?}")));
                }
                Some(_) => {}
            }
        }
    }

    /// The next frame, or `None` at `deadline`.
    fn read(&mut self, deadline: Instant) -> Result<Option<Message>, ClientError> {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Ok(None);
        }
        self.socket
            .get_ref()
            .set_read_timeout(Some(left))
            .map_err(tungstenite::Error::Io)?;
        match self.socket.read() {
            Ok(message) => Ok(Some(message)),
            Err(tungstenite::Error::Io(e)) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                Ok(None)
            }
            Err(e) => Err(e.into()),
        }
    }
}
