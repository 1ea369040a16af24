//! `case1 --foxglove` against `case1 --record`: the live view shows what the recording holds
//! (the same ground truth, decisions and scenes; only times differ: wall clock against
//! simulated), received by a client speaking Foxglove's protocol while the trial runs.

use std::time::{Duration, Instant};

use decision::PlannerConfig;
use live_view::client::{Received, WatchClient};
use live_view::LiveOptions;
use serde_json::Value;
use sim_client::live::{LiveTrial, Pace};
use sim_client::record::{DECISION_TOPIC, SCENE_TOPIC, TRIAL_TOPIC, VEHICLES_TOPIC};
use sim_client::{cases, recorded, Transport};

const PATIENCE: Duration = Duration::from_secs(60);
const TOPICS: [&str; 4] = [TRIAL_TOPIC, VEHICLES_TOPIC, DECISION_TOPIC, SCENE_TOPIC];

/// `scene` with its times taken out.
fn timeless(mut scene: Value) -> Value {
    for list in ["deletions", "entities"] {
        for item in scene[list].as_array_mut().expect("a list") {
            item.as_object_mut().expect("an object").remove("timestamp");
        }
    }
    scene
}

fn json(data: &[u8]) -> Value {
    serde_json::from_slice(data).expect("JSON")
}

#[test]
fn the_live_trial_shows_what_the_recording_holds() {
    let config = PlannerConfig::default();
    let info = recorded::trial_info("case1", &cases::case1_spec(1, config.perception.max_svs));
    // Room for the whole trial: the client reads after it.
    let mut options = LiveOptions::new("127.0.0.1:0".parse().expect("address"), "test");
    options.capacity = 4096;
    options.client_backlog = 4096;
    let mut live = LiveTrial::start(&options, info, Pace::Fast).expect("live view");
    let mut client = WatchClient::connect(live.server().local_addr(), PATIENCE).expect("connects");
    client
        .subscribe(&TOPICS, Instant::now() + PATIENCE)
        .expect("subscribed");
    for topic in TOPICS {
        assert!(live.server().wait_for_subscriber(topic, PATIENCE), "{topic}");
    }
    // The client reads while the trial runs, as a viewer does.
    let (received, messages) = std::sync::mpsc::channel::<Received>();
    let reader = std::thread::spawn(move || {
        while let Ok(Some(m)) = client.next_message(Instant::now() + PATIENCE) {
            if received.send(m).is_err() {
                break;
            }
        }
    });
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("case1.mcap");
    let (run, _) = recorded::record_case_observed("case1", &config, &Transport::InProcess, 1, &path, &mut live)
        .expect("the trial");
    assert!(live.server().flush(PATIENCE), "the publisher caught up");
    let counters = live.server().counters();
    assert_eq!((counters.dropped, counters.failed), (0, 0));
    let got: Vec<Received> = (0..counters.published)
        .map(|_| messages.recv_timeout(PATIENCE).expect("every published message"))
        .collect();
    assert_eq!(live.finish(), counters);
    reader.join().expect("reader");
    let live_of = |topic: &str| -> Vec<&Received> { got.iter().filter(|m| m.topic == topic).collect() };
    let recorded = recording::read_messages(&path).expect("read back");
    let recorded_of =
        |topic: &str| -> Vec<&recording::RecordedMessage> { recorded.iter().filter(|m| m.topic == topic).collect() };

    // Ground truth and decisions: byte for byte.
    for topic in [VEHICLES_TOPIC, DECISION_TOPIC] {
        let (shown, written) = (live_of(topic), recorded_of(topic));
        assert_eq!(shown.len(), written.len(), "{topic}");
        for (s, w) in shown.iter().zip(&written) {
            assert_eq!(s.data, w.data, "{topic}");
        }
    }
    assert_eq!(live_of(DECISION_TOPIC).len(), run.episode.decisions.len());
    // Scenes: the same but for their times, which are wall-clock live: the first step's time
    // plus the simulated time.
    let (shown, written) = (live_of(SCENE_TOPIC), recorded_of(SCENE_TOPIC));
    assert_eq!(shown.len(), written.len());
    let origin = shown[0].log_time_ns;
    for (s, w) in shown.iter().zip(&written) {
        assert_eq!(timeless(json(&s.data)), timeless(json(&w.data)));
        assert_eq!(s.log_time_ns - origin, w.log_time_ns);
        assert_eq!(
            json(&s.data)["entities"][0]["timestamp"]["nsec"],
            (s.log_time_ns % 1_000_000_000)
        );
    }
    // The trial's settings at the start and every simulated second.
    let trials = live_of(TRIAL_TOPIC);
    assert_eq!(trials[0].data, recorded_of(TRIAL_TOPIC)[0].data);
    assert_eq!(trials.len() as u64, run.episode.steps / 10 + 1);
}
