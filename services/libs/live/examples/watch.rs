//! Watches a live view from a terminal: subscribes to every topic and prints, every second,
//! the messages and bytes received per topic (or, with `--print TOPIC`, that topic's
//! messages). `--seconds N` stops after N seconds.
//!
//! ```text
//! cargo run --release -p live_view --example watch -- 127.0.0.1:8765 [--print /planner/response] [--seconds 60]
//! ```

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::time::{Duration, Instant};

use live_view::client::WatchClient;

type Error = Box<dyn std::error::Error>;

struct Args {
    addr: SocketAddr,
    print: Vec<String>,
    seconds: Option<u64>,
}

fn args() -> Result<Args, Error> {
    let mut args = std::env::args().skip(1);
    let mut addr = None;
    let (mut print, mut seconds) = (Vec::new(), None);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--print" => print.push(args.next().ok_or("--print TOPIC")?),
            "--seconds" => seconds = Some(args.next().ok_or("--seconds N")?.parse()?),
            _ if addr.is_none() => addr = Some(a.parse()?),
            _ => return Err(format!("unexpected argument `{a}`").into()),
        }
    }
    let addr = addr.unwrap_or(live_view::DEFAULT_ADDR);
    Ok(Args { addr, print, seconds })
}

fn main() -> Result<(), Error> {
    let args = args()?;
    let mut client = WatchClient::connect(args.addr, Duration::from_secs(10))?;
    // The server advertises its channels right after serverInfo, in one message.
    let channels = client.wait_for_channels(Instant::now() + Duration::from_secs(10))?;
    let topics: Vec<String> = channels.iter().map(|c| c.topic.clone()).collect();
    println!("{}: {}", client.server_name, topics.join(" "));
    let refs: Vec<&str> = topics.iter().map(String::as_str).collect();
    client.subscribe(&refs, Instant::now() + Duration::from_secs(10))?;
    let end = args.seconds.map(|s| Instant::now() + Duration::from_secs(s));
    let mut counts: BTreeMap<String, (u64, u64)> = BTreeMap::new();
    let mut next = Instant::now() + Duration::from_secs(1);
    while end.is_none_or(|end| Instant::now() < end) {
        let message = match client.next_message(next) {
            Ok(m) => m,
            Err(e) => {
                println!("{e}: {}", summary(&counts));
                return Ok(());
            }
        };
        if let Some(m) = message {
            let entry = counts.entry(m.topic.clone()).or_default();
            entry.0 += 1;
            entry.1 += m.data.len() as u64;
            if args.print.contains(&m.topic) {
                println!("{} {} {}", m.log_time_ns, m.topic, String::from_utf8_lossy(&m.data));
            }
        }
        if Instant::now() < next {
            continue;
        }
        next += Duration::from_secs(1);
        if args.print.is_empty() {
            println!("{}", summary(&counts));
        }
    }
    Ok(())
}

/// Messages and bytes per topic.
fn summary(counts: &BTreeMap<String, (u64, u64)>) -> String {
    let line: Vec<String> = counts
        .iter()
        .map(|(t, (n, bytes))| format!("{t} {n} msgs {} kB", bytes / 1000))
        .collect();
    line.join(" | ")
}
