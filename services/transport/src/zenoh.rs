//! The protocol over Zenoh: every Zenoh configuration of the project (the planner's, the
//! vehicles', the tests') and the vehicle's [`ZenohChannel`].

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use ::zenoh::bytes::Encoding;
use ::zenoh::query::{ConsolidationMode, Querier};
use ::zenoh::{Config, Session, Wait};
use protocol::{
    PlanRequest, PlanResponse, ResponseVerifier, WireFormat, ENCODING_BINCODE, ENCODING_JSON, ZENOH_PLAN_KEY,
};

use crate::{await_ready, Answer, ChannelError, PlanChannel};

/// Zenoh's error of a failed call, kept as the source.
pub type Cause = ::zenoh::Error;

/// The Zenoh mode of a session.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Talks to routers and peers it is told about (the planner).
    Peer,
    /// Connects to one router or peer (a vehicle).
    Client,
}

/// A Zenoh configuration: the file when given (any zenohd-style JSON5 file, e.g.
/// `deploy/zenoh/planner.json5`), else `mode` with scouting off (multicast and gossip), so
/// that sessions find each other only through `listen` / `connect`. Endpoints given here
/// replace the file's.
pub fn config(mode: Mode, file: Option<&Path>, listen: &[String], connect: &[String]) -> Result<Config, ChannelError> {
    let Some(path) = file else {
        let mut json = serde_json::json!({
            "mode": match mode { Mode::Peer => "peer", Mode::Client => "client" },
            "listen": { "endpoints": listen },
            "connect": { "endpoints": connect, "retry": reconnect() },
            "scouting": { "multicast": { "enabled": false }, "gossip": { "enabled": false } },
        });
        json.as_object_mut()
            .expect("an object")
            .extend(hardening().as_object().expect("an object").clone());
        return Config::from_json5(&json.to_string()).map_err(|source| ChannelError::ZenohConfig {
            what: "built-in".into(),
            source,
        });
    };
    let mut config = Config::from_file(path).map_err(|source| ChannelError::ZenohConfig {
        what: path.display().to_string(),
        source,
    })?;
    for (key, endpoints) in [("listen/endpoints", listen), ("connect/endpoints", connect)] {
        if !endpoints.is_empty() {
            let json = serde_json::Value::from(endpoints.to_vec()).to_string();
            config
                .insert_json5(key, &json)
                .map_err(|source| ChannelError::ZenohConfig {
                    what: key.into(),
                    source,
                })?;
        }
    }
    Ok(config)
}

/// How a session that lost its peer (a planner restarted, a router failed over) tries again:
/// after 50 ms, then twice as long each time up to 1 s. Zenoh's default first waits 1 s, and
/// that second is the whole outage a vehicle sees after a planner restart that takes a few
/// milliseconds; the cap keeps a long outage at one attempt a second. Set in the built-in
/// configurations and every shipped file that connects.
pub fn reconnect() -> serde_json::Value {
    serde_json::json!({ "period_init_ms": 50, "period_max_ms": 1000, "period_increase_factor": 2 })
}

/// Largest Zenoh message any session of the project accepts (a request is at most a few
/// KiB, see docs/protocol.md). Zenoh's own default is 1 GiB: a peer could make the planner
/// buffer that much for one query. A larger message is dropped while it is reassembled,
/// fragment by fragment, never buffered whole.
pub const MAX_MESSAGE_SIZE: usize = 64 * 1024;

/// The settings every Zenoh configuration of the project carries (the built-in ones here,
/// and every file in `deploy/zenoh/`, checked by a test):
///
/// * `transport/link/rx/max_message_size` = [`MAX_MESSAGE_SIZE`];
/// * queries on `hmdp/planner/plan` arriving at a session are re-marked congestion control
///   *drop*. A reply inherits its query's congestion control, and a querier may ask for
///   *block*: then one peer that stops reading its socket blocks the replier's sending for
///   seconds (until Zenoh closes that transport), and every other vehicle with it. With
///   *drop*, replies to a peer that does not read are dropped; nobody else waits.
pub fn hardening() -> serde_json::Value {
    serde_json::json!({
        "transport": { "link": { "rx": { "max_message_size": MAX_MESSAGE_SIZE } } },
        "qos": { "network": [{
            "id": "plan-replies-never-block",
            "messages": ["query"],
            "key_exprs": [ZENOH_PLAN_KEY],
            "flows": ["ingress", "egress"],
            "overwrite": { "congestion_control": "drop" },
        }] },
    })
}

/// The configuration of a client connecting to `endpoint` only.
pub fn client_config(endpoint: &str) -> Result<Config, ChannelError> {
    config(Mode::Client, None, &[], &[endpoint.to_owned()])
}

/// The Zenoh encoding of a wire format.
pub fn encoding(format: WireFormat) -> Encoding {
    match format {
        WireFormat::Json => Encoding::APPLICATION_JSON,
        WireFormat::Bincode => Encoding::from(ENCODING_BINCODE),
    }
}

/// The wire format a query or reply carries: JSON if its encoding is `application/json`,
/// else bincode.
pub fn format_of(encoding: Option<&Encoding>) -> WireFormat {
    match encoding {
        Some(e) if e.to_string().starts_with(ENCODING_JSON) => WireFormat::Json,
        _ => WireFormat::Bincode,
    }
}

/// Where a Zenoh planner is: an endpoint, a Zenoh configuration file, or both (the endpoint
/// then replaces the file's `connect` endpoints).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ZenohTarget {
    /// E.g. `tcp/127.0.0.1:7447`.
    pub endpoint: Option<String>,
    /// A zenohd-style JSON5 file, e.g. `deploy/zenoh/client.json5`.
    pub config_file: Option<PathBuf>,
    /// The planner's public key: answers that do not verify are refused (also the probe's,
    /// so that only the real planner makes a channel ready). `None`: every answer is taken.
    pub verifier: Option<ResponseVerifier>,
}

impl ZenohTarget {
    /// The session configuration of a vehicle.
    pub fn config(&self) -> Result<Config, ChannelError> {
        if self.endpoint.is_none() && self.config_file.is_none() {
            return Err(ChannelError::NoZenohTarget);
        }
        let connect: Vec<String> = self.endpoint.iter().cloned().collect();
        config(Mode::Client, self.config_file.as_deref(), &[], &connect)
    }

    fn describe(&self) -> String {
        self.endpoint
            .clone()
            .or_else(|| self.config_file.as_ref().map(|f| f.display().to_string()))
            .unwrap_or_default()
    }
}

/// Requests as Zenoh queries on [`ZENOH_PLAN_KEY`] (bincode payloads). Every reply is
/// read (no consolidation): with a key, a forged reply that arrives first does not hide the
/// planner's.
pub struct ZenohChannel {
    session: Session,
    querier: Querier<'static>,
    verifier: Option<ResponseVerifier>,
}

impl ZenohChannel {
    /// Opens a session to `target` (retrying until `ready_timeout`), declares a querier whose
    /// queries end after `query_timeout`, and waits until a planner answers a probe (the
    /// empty query, which comes back rejected).
    pub fn connect(
        target: &ZenohTarget,
        ready_timeout: Duration,
        query_timeout: Duration,
    ) -> Result<Self, ChannelError> {
        let since = Instant::now();
        let at = || format!("at {}", target.describe());
        let session = loop {
            match ::zenoh::open(target.config()?).wait() {
                Ok(s) => break s,
                Err(source) if since.elapsed() >= ready_timeout => {
                    return Err(ChannelError::Zenoh {
                        what: format!("cannot reach the planner {}", at()),
                        source,
                    })
                }
                Err(_) => std::thread::sleep(Duration::from_millis(100)),
            }
        };
        let querier = session
            .declare_querier(ZENOH_PLAN_KEY)
            .timeout(query_timeout)
            .consolidation(ConsolidationMode::None)
            .wait()
            .map_err(|source| ChannelError::Zenoh {
                what: "declaring the querier".into(),
                source,
            })?;
        let channel = Self {
            session,
            querier,
            verifier: target.verifier.clone(),
        };
        // Say why when only refused answers came: a planner without the key is not absent.
        let refused = std::cell::Cell::new(None);
        let at_why = || match refused.get() {
            Some(e) => format!("{} with a verified answer ({e})", at()),
            None => at(),
        };
        await_ready(since, ready_timeout, Duration::from_millis(100), at_why, || {
            let replies = channel.ask_raw(&[], WireFormat::Bincode, Duration::from_millis(500));
            if channel.verifier.is_none() {
                return Ok(!replies.is_empty());
            }
            let mut ready = false;
            for (bytes, _) in &replies {
                match channel.verified(bytes) {
                    Ok(_) => ready = true,
                    Err(Some(e)) => refused.set(Some(e)),
                    Err(None) => {}
                }
            }
            Ok(ready)
        })?;
        Ok(channel)
    }

    /// A reply decoded and, with a key, verified. `Err(None)`: it does not decode.
    fn verified(&self, bytes: &[u8]) -> Result<PlanResponse, Option<protocol::VerifyError>> {
        let response = protocol::decode_bincode::<PlanResponse>(bytes).map_err(|e| {
            tracing::warn!("undecodable answer: {e}");
            None
        })?;
        match &self.verifier {
            Some(verifier) => verifier.verify(&response).map(|()| response).map_err(Some),
            None => Ok(response),
        }
    }

    /// Every reply payload to one query of `payload` in `format`, until every queryable has
    /// answered, the querier's timeout, or `wait` (after the first reply).
    pub fn ask_raw(&self, payload: &[u8], format: WireFormat, wait: Duration) -> Vec<(Vec<u8>, Instant)> {
        let deadline = Instant::now() + wait;
        let mut replies_seen = Vec::new();
        let Ok(replies) = self
            .querier
            .get()
            .payload(payload.to_vec())
            .encoding(encoding(format))
            .wait()
        else {
            return replies_seen;
        };
        while let Ok(Some(reply)) = replies.recv_deadline(deadline) {
            if let Ok(sample) = reply.result() {
                replies_seen.push((sample.payload().to_bytes().into_owned(), Instant::now()));
            }
            if deadline <= Instant::now() {
                break;
            }
        }
        replies_seen
    }

    /// The Zenoh session (to declare more entities on it).
    pub fn session(&self) -> &Session {
        &self.session
    }
}

impl PlanChannel for ZenohChannel {
    fn exchange(&mut self, request: PlanRequest, wait: Duration) -> Result<Answer, ChannelError> {
        let mut answer = Answer::default();
        // Answers after the first are counted, not used.
        for (bytes, at) in self.ask_raw(&protocol::encode_bincode(&request), WireFormat::Bincode, wait) {
            match self.verified(&bytes) {
                Ok(response) if answer.response.is_none() => {
                    answer.response = Some(response);
                    answer.answered_at = Some(at);
                }
                Ok(_) => answer.extra_responses += 1,
                Err(Some(e)) => {
                    tracing::warn!(sequence = request.sequence, "answer refused: {e}");
                    answer.refused.push(e);
                }
                Err(None) => {}
            }
        }
        Ok(answer)
    }

    fn name(&self) -> &'static str {
        "zenoh"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The hardening in a configuration: the message size bound and the droppable queries.
    fn assert_hardened(config: &Config, what: &str) {
        let size = config.get_json("transport/link/rx/max_message_size").unwrap();
        assert_eq!(size, MAX_MESSAGE_SIZE.to_string(), "{what}: max_message_size");
        let qos: serde_json::Value = serde_json::from_str(&config.get_json("qos/network").unwrap()).unwrap();
        let rule = qos
            .as_array()
            .and_then(|rules| rules.iter().find(|r| r["id"] == "plan-replies-never-block"))
            .unwrap_or_else(|| panic!("{what}: no qos rule plan-replies-never-block in {qos}"));
        assert_eq!(rule["overwrite"]["congestion_control"], "drop", "{what}");
        assert_eq!(rule["messages"], serde_json::json!(["query"]), "{what}");
        assert_eq!(rule["key_exprs"], serde_json::json!([ZENOH_PLAN_KEY]), "{what}");
    }

    #[test]
    fn built_in_configurations_are_hardened() {
        for mode in [Mode::Peer, Mode::Client] {
            let config = config(mode, None, &["tcp/127.0.0.1:7447".into()], &[]).unwrap();
            assert_hardened(&config, &format!("{mode:?}"));
        }
    }

    /// The reconnection retry of a configuration that connects.
    fn assert_reconnects_fast(config: &Config, what: &str) {
        let retry: serde_json::Value = serde_json::from_str(&config.get_json("connect/retry").unwrap()).unwrap();
        for (key, want) in reconnect().as_object().unwrap() {
            assert_eq!(
                retry[key].as_f64(),
                want.as_f64(),
                "{what}: connect/retry/{key} in {retry}"
            );
        }
    }

    #[test]
    fn built_in_configurations_reconnect_fast() {
        for mode in [Mode::Peer, Mode::Client] {
            let config = config(mode, None, &[], &["tcp/127.0.0.1:7447".into()]).unwrap();
            assert_reconnects_fast(&config, &format!("{mode:?}"));
        }
    }

    #[test]
    fn every_shipped_configuration_is_hardened() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../deploy/zenoh");
        let (mut checked, mut connecting) = (0, 0);
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "json5") {
                let config = Config::from_file(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                assert_hardened(&config, &path.display().to_string());
                let endpoints: serde_json::Value =
                    serde_json::from_str(&config.get_json("connect/endpoints").unwrap()).unwrap();
                if endpoints.as_array().is_some_and(|e| !e.is_empty()) {
                    assert_reconnects_fast(&config, &path.display().to_string());
                    connecting += 1;
                }
                checked += 1;
            }
        }
        assert!(checked >= 6, "only {checked} files in {}", dir.display());
        assert!(connecting >= 4, "only {connecting} files connect");
    }
}
