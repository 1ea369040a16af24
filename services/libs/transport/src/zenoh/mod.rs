//! The protocol over Zenoh: every Zenoh configuration of the project (the planner's, the
//! vehicles', the tests'), the vehicle's [`ZenohChannel`] and how it shares the vehicles
//! among several planner instances ([`instances`]).

mod channel;
pub mod instances;
pub mod security;

use std::path::{Path, PathBuf};
use std::time::Duration;

use ::zenoh::bytes::Encoding;
use ::zenoh::Config;
use protocol::{
    ResponseVerifier, WireFormat, ENCODING_BINCODE, ENCODING_JSON, ZENOH_PLAN_INSTANCE_KEYS, ZENOH_PLAN_KEY,
};

pub use channel::ZenohChannel;

use crate::ChannelError;

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
        json["transport"]["link"]["tx"] = lease();
        json["transport"]["unicast"] = accept();
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

/// How long a session's peers wait for a sign of life before they drop it (its lease, which
/// each side announces and the other enforces), and how many keep-alives it sends per lease:
/// 3 s and 4 (Zenoh's default: 10 s). Set in the built-in configurations; a planner's is
/// shorter ([`planner_lease`]).
pub fn lease() -> serde_json::Value {
    serde_json::json!({ "lease": 3000, "keep_alive": 4 })
}

/// A planner's lease: 600 ms, a keep-alive every 150 ms. It is how long a router keeps a
/// hung (e.g. SIGSTOPped) planner's queryables and liveliness token: a client that only
/// knows `hmdp/planner/plan` is routed to one instance, and reaches another only once its
/// router has dropped that one, so the lease bounds what a hang costs such a client
/// (docs/deploy.md, "Scaling out"; the vehicles that pick an instance retry after 150 ms
/// anyway). A planner sends far more often than every 150 ms while it serves; idle, it
/// must get a core within 450 ms, or its router drops it and it reconnects (50 ms later).
/// Set by `planner serve` in its built-in configuration and in the shipped planner files.
pub fn planner_lease() -> serde_json::Value {
    serde_json::json!({ "lease": PLANNER_LEASE_MS, "keep_alive": 4 })
}

/// A planner's lease, ms (see [`planner_lease`]).
pub const PLANNER_LEASE_MS: u64 = 600;

/// How a session that listens admits new connections (`transport/unicast`): up to 1000
/// connections may be in Zenoh's session handshake at once (`accept_pending`, Zenoh's
/// default 100), each for at most 2 s (`accept_timeout`, default 10 s). Beyond
/// `accept_pending` Zenoh closes every new connection at once, so with the defaults 100 idle
/// TCP sockets (or 10 new silent ones a second) kept every new vehicle out. The limit is far above
/// what a fleet opens at once; 2 s is ample for the handshake's two round trips. Set in the
/// built-in configurations and every shipped file of a process that listens or may listen
/// (the routers, the planners; docs/hostile-peers.md,"Connection floods").
pub fn accept() -> serde_json::Value {
    serde_json::json!({ "accept_timeout": ACCEPT_TIMEOUT_MS, "accept_pending": ACCEPT_PENDING })
}

/// `transport/unicast/accept_timeout`, ms (see [`accept`]).
pub const ACCEPT_TIMEOUT_MS: u64 = 2000;

/// `transport/unicast/accept_pending` (see [`accept`]).
pub const ACCEPT_PENDING: usize = 1000;

/// How long a TLS listener waits for a connection's TLS handshake, ms (Zenoh's default
/// 10 s): a connection that never completes it holds a socket no longer than this. Zenoh
/// takes it from the listen endpoint (`tls/HOST:PORT#tls_handshake_timeout_ms=5000`), as in
/// `deploy/zenoh/router-tls.json5`.
pub const TLS_HANDSHAKE_TIMEOUT_MS: u64 = 5000;

/// The most each link a TLS listener accepts may send, bytes of TLS plaintext a second:
/// a vehicle's link is read no faster, and what it sends beyond waits in its own TCP
/// connection. About 1.8 times a vehicle sending 64 SVs in JSON at 20 Hz, 6 times the
/// same in bincode (docs/hostile-peers.md,"TLS links"). The workspace's patched zenoh-link-tls
/// takes it from the listen endpoint (`...#ingress_bytes_per_s=524288`), as in
/// `deploy/zenoh/router-tls.json5`; Zenoh's own TLS links have no such limit.
pub const TLS_INGRESS_BYTES_PER_S: u64 = 512 * 1024;

/// The burst a TLS link may send at once beyond [`TLS_INGRESS_BYTES_PER_S`], bytes
/// (`...#ingress_burst_bytes=262144`): 18 requests of 64 SVs in JSON, 60 in bincode.
pub const TLS_INGRESS_BURST_BYTES: u64 = 256 * 1024;

/// Largest Zenoh message any session of the project accepts (a request is at most a few
/// KiB, see docs/protocol.md). Zenoh's own default is 1 GiB: a peer could make the planner
/// buffer that much for one query. A larger message is dropped while it is reassembled,
/// fragment by fragment, never buffered whole.
pub const MAX_MESSAGE_SIZE: usize = 64 * 1024;

/// The settings every Zenoh configuration of the project carries (the built-in ones here,
/// and every file in `deploy/zenoh/`, checked by a test):
///
/// * `transport/link/rx/max_message_size` = [`MAX_MESSAGE_SIZE`];
/// * queries on `hmdp/planner/plan` and on the instances' keys `hmdp/planner/plan/*`
///   arriving at a session are re-marked congestion control
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
            "key_exprs": [ZENOH_PLAN_KEY, ZENOH_PLAN_INSTANCE_KEYS],
            "flows": ["ingress", "egress"],
            "overwrite": { "congestion_control": "drop" },
        }] },
    })
}

/// Refuses a request payload that no planner could receive: every session of the project
/// drops a message above [`MAX_MESSAGE_SIZE`] while reassembling it, and nothing goes back
/// to the sender (docs/protocol.md, "Size").
pub fn check_request_size(bytes: usize) -> Result<(), ChannelError> {
    // The payload travels with the key expression and Zenoh's headers: keep a margin.
    let max = MAX_MESSAGE_SIZE - REQUEST_OVERHEAD;
    if bytes > max {
        return Err(ChannelError::RequestTooLarge { bytes, max });
    }
    Ok(())
}

/// What a query adds to its payload on the wire, at most (the key expression, the
/// encoding, Zenoh's headers), with room to spare.
pub const REQUEST_OVERHEAD: usize = 1024;

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
    /// How a request fails over between planner instances.
    pub failover: Failover,
    /// Accept unverified answers from a planner beyond this host (`--insecure`). Without a
    /// `verifier`, a session that can reach beyond this host is refused unless this is set
    /// ([`ZenohTarget::check_security`]).
    pub insecure: bool,
}

/// How a vehicle's channel shares out its requests when several planner instances serve
/// (docs/deploy.md, "Scaling out"): each request goes to the vehicle's first live instance
/// in rendezvous order, and once more to the next one if no valid answer came in time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Failover {
    /// Without a valid answer this long after sending (or when the instance's query ended
    /// without one), the request goes to the next instance, once. Well inside the 380 ms a
    /// planner is given, far above a solve (a few ms).
    pub retry_after: Duration,
    /// How long an instance that left a query unanswered is tried last.
    pub suspect_for: Duration,
}

impl Default for Failover {
    fn default() -> Self {
        Self {
            retry_after: Duration::from_millis(150),
            suspect_for: Duration::from_secs(2),
        }
    }
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

    /// Refuses a session that may meet a planner beyond this host without the planner's
    /// public key: there, anyone who can declare a queryable on the Zenoh network can answer
    /// and would be believed. On this host alone (loopback endpoints, no scouting) unsigned
    /// answers stay allowed, as in the demos; with `insecure` the session goes ahead, with a
    /// warning in the log.
    pub fn check_security(&self, config: &Config) -> Result<(), ChannelError> {
        if self.verifier.is_some() {
            return Ok(());
        }
        let reach = security::beyond_this_host(config);
        if reach.is_empty() {
            return Ok(());
        }
        let reach = reach.join(", ");
        if self.insecure {
            tracing::warn!(
                "INSECURE: answers from the planner at {} are not verified ({reach}): anyone who can answer \
                 on that network commands this vehicle; give the planner's public key",
                self.describe()
            );
            return Ok(());
        }
        Err(ChannelError::UnverifiedRemotePlanner { reach })
    }

    pub(crate) fn describe(&self) -> String {
        self.endpoint
            .clone()
            .or_else(|| self.config_file.as_ref().map(|f| f.display().to_string()))
            .unwrap_or_default()
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
        assert_eq!(
            rule["key_exprs"],
            serde_json::json!([ZENOH_PLAN_KEY, ZENOH_PLAN_INSTANCE_KEYS]),
            "{what}"
        );
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
    fn a_request_no_planner_could_receive_is_refused_before_it_is_sent() {
        let largest = MAX_MESSAGE_SIZE - REQUEST_OVERHEAD;
        assert!(check_request_size(largest).is_ok());
        match check_request_size(largest + 1) {
            Err(ChannelError::RequestTooLarge { bytes, max }) => assert_eq!((bytes, max), (largest + 1, largest)),
            other => panic!("{other:?}"),
        }
        // The largest valid request is far inside the bound.
        let mut request = protocol::worked_example_request(1, 1);
        let first = *request.svs.iter().next().unwrap();
        for id in 2..=protocol::MAX_SVS as u32 {
            let _ = protocol::containers::Vector::push(&mut request.svs, protocol::SvObservation { id, ..first });
        }
        assert_eq!(protocol::containers::Vector::len(&request.svs), protocol::MAX_SVS);
        assert!(check_request_size(protocol::encode_json(&request).len()).is_ok());
    }

    #[test]
    fn built_in_configurations_reconnect_fast() {
        for mode in [Mode::Peer, Mode::Client] {
            let config = config(mode, None, &[], &["tcp/127.0.0.1:7447".into()]).unwrap();
            assert_reconnects_fast(&config, &format!("{mode:?}"));
        }
    }

    /// A planner's lease: a hung planner is dropped by its router after 600 ms, not 10 s.
    fn assert_planner_lease(config: &Config, what: &str) {
        for (key, want) in planner_lease().as_object().unwrap() {
            let got = config.get_json(&format!("transport/link/tx/{key}")).unwrap();
            assert_eq!(got, want.to_string(), "{what}: transport/link/tx/{key}");
        }
    }

    #[test]
    fn built_in_configurations_have_a_lease_shorter_than_zenohs() {
        for mode in [Mode::Peer, Mode::Client] {
            let config = config(mode, None, &[], &[]).unwrap();
            for (key, want) in lease().as_object().unwrap() {
                let got = config.get_json(&format!("transport/link/tx/{key}")).unwrap();
                assert_eq!(got, want.to_string(), "{mode:?}: transport/link/tx/{key}");
            }
        }
    }

    /// The admission limits of a session that listens (a flood of idle or junk connections
    /// must not keep vehicles out).
    fn assert_accepts_under_floods(config: &Config, what: &str) {
        for (key, want) in accept().as_object().unwrap() {
            let got = config.get_json(&format!("transport/unicast/{key}")).unwrap();
            assert_eq!(got, want.to_string(), "{what}: transport/unicast/{key}");
        }
    }

    #[test]
    fn built_in_configurations_accept_under_floods() {
        for mode in [Mode::Peer, Mode::Client] {
            let config = config(mode, None, &["tcp/127.0.0.1:7447".into()], &[]).unwrap();
            assert_accepts_under_floods(&config, &format!("{mode:?}"));
        }
    }

    /// The endpoints under `key` (`listen/endpoints`, ...) for the configuration's own mode
    /// (Zenoh's defaults depend on the mode).
    fn endpoints(config: &Config, key: &str) -> Vec<String> {
        let value: serde_json::Value = serde_json::from_str(&config.get_json(key).unwrap()).unwrap();
        let mode: serde_json::Value = serde_json::from_str(&config.get_json("mode").unwrap()).unwrap();
        let list = match &value {
            serde_json::Value::Object(by_mode) => by_mode.get(mode.as_str().unwrap_or("peer")),
            other => Some(other),
        };
        list.and_then(|l| l.as_array())
            .map(|l| l.iter().filter_map(|e| e.as_str().map(str::to_owned)).collect())
            .unwrap_or_default()
    }

    /// A TLS listener's handshake timeout (Zenoh's default: 10 s) and its links' ingress
    /// limit (none by default), set in its endpoint.
    fn assert_tls_listeners_bounded(endpoints: &[String], what: &str) {
        for endpoint in endpoints.iter().filter(|e| e.starts_with("tls/")) {
            let parsed: zenoh::config::EndPoint = endpoint.parse().unwrap();
            let config = parsed.config();
            for (key, value) in [
                ("tls_handshake_timeout_ms", TLS_HANDSHAKE_TIMEOUT_MS),
                ("ingress_bytes_per_s", TLS_INGRESS_BYTES_PER_S),
                ("ingress_burst_bytes", TLS_INGRESS_BURST_BYTES),
            ] {
                assert_eq!(
                    config.get(key),
                    Some(value.to_string().as_str()),
                    "{what}: {endpoint}: {key}"
                );
            }
        }
    }

    /// Set at build time by `.cargo/config.toml` for zenoh-link-tls and zenoh-link-tcp
    /// (docs/hostile-peers.md,"Connection floods"); read here from the same build environment.
    #[test]
    fn flood_settings_are_set_for_the_build() {
        assert_eq!(option_env!("TLS_ACCEPT_THROTTLE_TIME"), Some("1000"));
        assert_eq!(option_env!("TCP_LINGER_TIMEOUT"), Some("0"));
    }

    #[test]
    fn every_shipped_configuration_is_hardened() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../deploy/zenoh");
        let (mut checked, mut connecting, mut planners, mut admitting) = (0, 0, 0, 0);
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "json5") {
                let config = Config::from_file(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                assert_hardened(&config, &path.display().to_string());
                let planner = path
                    .file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with("planner"));
                if planner {
                    assert_planner_lease(&config, &path.display().to_string());
                    planners += 1;
                }
                let listen = endpoints(&config, "listen/endpoints");
                if planner || !listen.is_empty() {
                    assert_accepts_under_floods(&config, &path.display().to_string());
                    assert_tls_listeners_bounded(&listen, &path.display().to_string());
                    admitting += 1;
                }
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
        assert_eq!(planners, 3, "planner.json5, planner-local.json5 and planner-tls.json5");
        assert_eq!(admitting, 5, "the routers and the planners");
    }
}
