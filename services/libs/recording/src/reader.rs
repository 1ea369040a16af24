//! Reading recordings back.

use std::collections::{HashMap, VecDeque};
use std::path::{Path, PathBuf};

use protocol::{PlanRequest, PlanResponse};

use crate::error::{RecordingError, Result};
use crate::{REQUEST_TOPIC, RESPONSE_TOPIC};

/// One message of a recording.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedMessage {
    pub topic: String,
    /// Schema name (`None` for a channel without schema).
    pub schema_name: Option<String>,
    pub message_encoding: String,
    pub log_time_ns: u64,
    pub data: Vec<u8>,
}

impl RecordedMessage {
    /// Decodes the JSON payload (see [`crate::json`]); `index` and `path` name it in the
    /// error.
    pub fn decode<T: serde::de::DeserializeOwned>(&self, path: &Path, index: usize, what: &'static str) -> Result<T> {
        if self.message_encoding != "json" {
            return Err(RecordingError::Encoding {
                path: path.to_owned(),
                topic: self.topic.clone(),
                encoding: self.message_encoding.clone(),
            });
        }
        crate::json::from_slice(&self.data).map_err(|source| RecordingError::Decode {
            path: path.to_owned(),
            topic: self.topic.clone(),
            index,
            what,
            source,
        })
    }
}

/// Every message of the file at `path`, in file order.
pub fn read_messages(path: &Path) -> Result<Vec<RecordedMessage>> {
    let bytes = std::fs::read(path).map_err(|e| RecordingError::io(path, e))?;
    let stream = mcap::MessageStream::new(&bytes).map_err(|e| RecordingError::mcap(path, e))?;
    let mut out = Vec::new();
    for message in stream {
        let m = message.map_err(|e| RecordingError::mcap(path, e))?;
        out.push(RecordedMessage {
            topic: m.channel.topic.clone(),
            schema_name: m.channel.schema.as_ref().map(|s| s.name.clone()),
            message_encoding: m.channel.message_encoding.clone(),
            log_time_ns: m.log_time,
            data: m.data.into_owned(),
        });
    }
    Ok(out)
}

/// A recorded request with the answer recorded for it.
#[derive(Debug, Clone, PartialEq)]
pub struct Exchange {
    pub request: PlanRequest,
    pub request_time_ns: u64,
    /// `None` when the recording holds no answer (it ended first, or the answer was dropped).
    pub response: Option<PlanResponse>,
}

/// The exchanges of one or more recordings, in request order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Exchanges {
    pub exchanges: Vec<Exchange>,
    /// Answers with no recorded request.
    pub unmatched_responses: usize,
}

/// Reads the requests and answers of `paths` (the files of one rotated recording, in order)
/// and pairs them by vehicle and sequence. A file set without a request is
/// [`RecordingError::MissingChannel`].
pub fn read_exchanges(paths: &[PathBuf]) -> Result<Exchanges> {
    let mut out = Exchanges::default();
    // Unanswered requests by (vehicle, sequence), oldest first.
    let mut open: HashMap<(u64, u64), VecDeque<usize>> = HashMap::new();
    for path in paths {
        for (index, m) in read_messages(path)?.iter().enumerate() {
            match m.topic.as_str() {
                REQUEST_TOPIC => {
                    let request: PlanRequest = m.decode(path, index, "PlanRequest")?;
                    open.entry((request.vehicle_id, request.sequence))
                        .or_default()
                        .push_back(out.exchanges.len());
                    out.exchanges.push(Exchange {
                        request,
                        request_time_ns: m.log_time_ns,
                        response: None,
                    });
                }
                RESPONSE_TOPIC => {
                    let response: PlanResponse = m.decode(path, index, "PlanResponse")?;
                    let slot = open
                        .get_mut(&(response.vehicle_id, response.sequence))
                        .and_then(VecDeque::pop_front);
                    match slot {
                        Some(i) => out.exchanges[i].response = Some(response),
                        None => out.unmatched_responses += 1,
                    }
                }
                _ => {}
            }
        }
    }
    if out.exchanges.is_empty() {
        return Err(RecordingError::MissingChannel {
            path: paths.first().cloned().unwrap_or_default(),
            topic: REQUEST_TOPIC.to_owned(),
            needed: "PlanRequest messages to re-decide",
        });
    }
    Ok(out)
}
