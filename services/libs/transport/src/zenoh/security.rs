//! Whether a vehicle's session can meet a planner beyond this host, where an unverified
//! answer may come from anyone on the network (docs/deploy.md, "Signed answers").

use std::net::{IpAddr, ToSocketAddrs};

use ::zenoh::Config;

/// What lets a session with this configuration reach beyond this host: each endpoint it
/// connects to (or, in peer mode, listens on) that is not a loopback address, and scouting
/// that may find peers on the network. Empty: only this host.
pub fn beyond_this_host(config: &Config) -> Vec<String> {
    let mut reach: Vec<String> = endpoints(config, "connect/endpoints")
        .into_iter()
        .filter(|e| !is_loopback_endpoint(e))
        .collect();
    let mode = json(config, "mode").and_then(|m| m.as_str().map(str::to_owned));
    let peer = mode.as_deref() != Some("client");
    if peer {
        reach.extend(
            endpoints(config, "listen/endpoints")
                .into_iter()
                .filter(|e| !is_loopback_endpoint(e))
                .map(|e| format!("listening on {e}")),
        );
    }
    if enabled(config, "scouting/multicast/enabled") {
        reach.push("multicast scouting".into());
    }
    if peer && enabled(config, "scouting/gossip/enabled") {
        reach.push("gossip scouting".into());
    }
    reach
}

fn json(config: &Config, key: &str) -> Option<serde_json::Value> {
    config
        .get_json(key)
        .ok()
        .and_then(|text| serde_json::from_str(&text).ok())
}

fn enabled(config: &Config, key: &str) -> bool {
    json(config, key).and_then(|v| v.as_bool()).unwrap_or(false)
}

/// The endpoints under `key` for the configuration's own mode (a list, or one list per mode).
fn endpoints(config: &Config, key: &str) -> Vec<String> {
    let Some(value) = json(config, key) else {
        return Vec::new();
    };
    let mode = json(config, "mode").and_then(|m| m.as_str().map(str::to_owned));
    let list = match &value {
        serde_json::Value::Object(by_mode) => by_mode.get(mode.as_deref().unwrap_or("peer")),
        other => Some(other),
    };
    list.and_then(|l| l.as_array())
        .map(|l| l.iter().filter_map(|e| e.as_str().map(str::to_owned)).collect())
        .unwrap_or_default()
}

/// Whether a Zenoh endpoint (`tcp/127.0.0.1:7447`, `tls/localhost:7447#...`,
/// `unixsock-stream/PATH`) stays on this host: a Unix socket, or an IP protocol to a
/// loopback address or to a name that resolves to loopback addresses only. A name that does
/// not resolve, an unspecified address (0.0.0.0) or any other protocol counts as beyond.
pub fn is_loopback_endpoint(endpoint: &str) -> bool {
    let locator = endpoint.split(['?', '#']).next().unwrap_or_default();
    let Some((protocol, address)) = locator.split_once('/') else {
        return false;
    };
    match protocol {
        "unixsock-stream" | "unixpipe" => true,
        "tcp" | "tls" | "udp" | "quic" | "ws" => is_loopback_address(address),
        _ => false,
    }
}

/// `HOST:PORT` or `[V6]:PORT` names this host's loopback interface only.
fn is_loopback_address(address: &str) -> bool {
    let Some((host, port)) = address.rsplit_once(':') else {
        return false;
    };
    let host = host.trim_start_matches('[').trim_end_matches(']');
    if let Ok(ip) = host.parse::<IpAddr>() {
        return ip.is_loopback();
    }
    let Ok(port) = port.parse::<u16>() else {
        return false;
    };
    match (host, port).to_socket_addrs() {
        Ok(addresses) => {
            let addresses: Vec<_> = addresses.collect();
            !addresses.is_empty() && addresses.iter().all(|a| a.ip().is_loopback())
        }
        Err(_) => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::zenoh::{config, Mode};

    #[test]
    fn loopback_endpoints_stay_on_this_host() {
        for local in [
            "tcp/127.0.0.1:7447",
            "tls/127.0.0.1:7447#tls_handshake_timeout_ms=5000",
            "tcp/localhost:7447",
            "tcp/[::1]:7447",
            "tcp/127.8.9.1:1",
            "unixsock-stream//tmp/hmdp.sock",
        ] {
            assert!(is_loopback_endpoint(local), "{local}");
        }
        for beyond in [
            "tcp/192.0.2.10:7447",
            "tls/hmdp-router.invalid:7447",
            "tcp/0.0.0.0:7447",
            "tcp/[2001:db8::1]:7447",
            "serial//dev/ttyUSB0",
            "tcp/127.0.0.1",
            "garbage",
        ] {
            assert!(!is_loopback_endpoint(beyond), "{beyond}");
        }
    }

    #[test]
    fn a_session_reaches_beyond_by_an_endpoint_or_by_scouting() {
        let local = config(Mode::Client, None, &[], &["tcp/127.0.0.1:7447".into()]).unwrap();
        assert!(beyond_this_host(&local).is_empty());
        let remote = config(Mode::Client, None, &[], &["tcp/192.0.2.10:7447".into()]).unwrap();
        assert_eq!(beyond_this_host(&remote), ["tcp/192.0.2.10:7447"]);
        let mut scouting = local.clone();
        scouting.insert_json5("scouting/multicast/enabled", "true").unwrap();
        assert_eq!(beyond_this_host(&scouting), ["multicast scouting"]);
        // A peer may also be reached by whoever connects to it.
        let listening = config(Mode::Peer, None, &["tcp/0.0.0.0:7447".into()], &[]).unwrap();
        assert_eq!(beyond_this_host(&listening), ["listening on tcp/0.0.0.0:7447"]);
    }

    #[test]
    fn the_shipped_vehicle_files_reach_beyond_this_host() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../deploy/zenoh");
        for file in ["client.json5", "client-tls.json5"] {
            let config = Config::from_file(dir.join(file)).unwrap();
            assert!(!beyond_this_host(&config).is_empty(), "{file}");
        }
    }
}
