//! The writer and the reader together: what is written is read back, rotation splits the
//! file, and bad files are typed errors.

use std::path::PathBuf;
use std::time::Instant;

use protocol::containers::Vector;
use protocol::{EgoState, PlanRequest, PlanResponse, RejectReason, Rejected, Road, SvObservation};
use recording::{
    read_exchanges, read_messages, McapSink, PlanRecorder, RecorderOptions, RecordingError, Rotation, PLANNER_CHANNELS,
    REQUEST_TOPIC, RESPONSE_TOPIC, STATS_TOPIC,
};

fn request(vehicle: u64, sequence: u64) -> PlanRequest {
    PlanRequest::new(
        vehicle,
        sequence,
        sequence * 400_000_000,
        Road {
            lanes: 3,
            lane_width_m: 3.5,
            speed_limit_mps: 30.0,
        },
        EgoState::default(),
    )
}

fn response(vehicle: u64, sequence: u64) -> PlanResponse {
    PlanResponse::rejected(
        vehicle,
        sequence,
        Rejected::new(RejectReason::OutOfRange, "ego.v_mps"),
        7,
    )
}

fn dir() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}

#[test]
fn recorded_exchanges_are_read_back_paired() {
    let d = dir();
    let path = d.path().join("r.mcap");
    let recorder = PlanRecorder::start(&RecorderOptions::new(&path)).expect("recorder");
    let t0 = Instant::now();
    for s in 0..20 {
        let reply = recorder.wrap_reply(&request(1 + s % 2, s), t0, |_| {});
        // Answers in another order than the requests.
        if !s.is_multiple_of(3) {
            reply(response(1 + s % 2, s));
        } else {
            drop(reply);
        }
    }
    recorder.stats(&serde_json::json!({ "answered": 13 }));
    let summary = recorder.finish().expect("finished");
    assert_eq!(summary.files, vec![path.clone()]);
    assert_eq!(summary.dropped, 0);
    assert_eq!(summary.messages, 20 + 13 + 1);
    let exchanges = read_exchanges(std::slice::from_ref(&path)).expect("read");
    assert_eq!(exchanges.exchanges.len(), 20);
    for (s, e) in exchanges.exchanges.iter().enumerate() {
        let s = s as u64;
        assert_eq!(e.request, request(1 + s % 2, s));
        assert_eq!(e.response, (!s.is_multiple_of(3)).then(|| response(1 + s % 2, s)));
    }
    let topics: Vec<String> = read_messages(&path)
        .expect("read")
        .into_iter()
        .map(|m| m.topic)
        .collect();
    assert_eq!(topics.iter().filter(|t| *t == STATS_TOPIC).count(), 1);
}

#[test]
fn a_full_channel_drops_and_counts_instead_of_blocking() {
    let d = dir();
    let mut options = RecorderOptions::new(d.path().join("small.mcap"));
    options.capacity = 1;
    let recorder = PlanRecorder::start(&options).expect("recorder");
    for s in 0..2000 {
        recorder.request(&request(1, s), Instant::now());
    }
    let summary = recorder.finish().expect("finished");
    assert_eq!(summary.messages + summary.dropped, 2000, "{summary:?}");
}

#[test]
fn rotation_by_size_splits_into_complete_files() {
    let d = dir();
    let path = d.path().join("big.mcap");
    let rotation = Rotation {
        max_bytes: Some(20_000),
        max_duration: None,
    };
    let mut sink = McapSink::create(&path, PLANNER_CHANNELS.to_vec(), rotation).expect("sink");
    for s in 0..200 {
        sink.write_json(0, s * 1000, &request(1, s)).expect("written");
    }
    let files: Vec<PathBuf> = sink.finish().expect("finished");
    assert!(files.len() > 2, "{files:?}");
    assert_eq!(files[1], d.path().join("big.1.mcap"));
    let exchanges = read_exchanges(&files).expect("read");
    let sequences: Vec<u64> = exchanges.exchanges.iter().map(|e| e.request.sequence).collect();
    assert_eq!(sequences, (0..200).collect::<Vec<_>>());
}

#[test]
fn bad_files_are_typed_errors() {
    let d = dir();
    let path = d.path().join("ok.mcap");
    let mut sink = McapSink::create(&path, PLANNER_CHANNELS.to_vec(), Rotation::default()).expect("sink");
    for s in 0..50 {
        sink.write_json(0, s, &request(1, s)).expect("written");
        sink.write_json(1, s, &response(1, s)).expect("written");
    }
    sink.finish().expect("finished");
    let bytes = std::fs::read(&path).expect("read");
    let truncated = d.path().join("truncated.mcap");
    std::fs::write(&truncated, &bytes[..bytes.len() * 2 / 3]).expect("written");
    assert!(matches!(read_exchanges(&[truncated]), Err(RecordingError::Mcap { .. })));
    let garbage = d.path().join("garbage.mcap");
    std::fs::write(&garbage, b"not an mcap file at all").expect("written");
    assert!(matches!(read_exchanges(&[garbage]), Err(RecordingError::Mcap { .. })));
    let missing = d.path().join("missing.mcap");
    assert!(matches!(read_exchanges(&[missing]), Err(RecordingError::Io { .. })));
    // A file with only statistics has nothing to replay.
    let stats_only = d.path().join("stats.mcap");
    let mut sink = McapSink::create(&stats_only, PLANNER_CHANNELS.to_vec(), Rotation::default()).expect("sink");
    sink.write_json(2, 0, &serde_json::json!({})).expect("written");
    sink.finish().expect("finished");
    match read_exchanges(&[stats_only]) {
        Err(RecordingError::MissingChannel { topic, .. }) => assert_eq!(topic, REQUEST_TOPIC),
        other => panic!("{other:?}"),
    }
    // A response that is not a PlanResponse names its message.
    let wrong = d.path().join("wrong.mcap");
    let mut sink = McapSink::create(&wrong, PLANNER_CHANNELS.to_vec(), Rotation::default()).expect("sink");
    sink.write_json(0, 0, &request(1, 0)).expect("written");
    sink.write_json(1, 1, &serde_json::json!({ "version": 2 }))
        .expect("written");
    sink.finish().expect("finished");
    match read_exchanges(&[wrong]) {
        Err(RecordingError::Decode { topic, index, .. }) => {
            assert_eq!(topic, RESPONSE_TOPIC);
            assert_eq!(index, 1);
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn non_finite_floats_are_recorded_so_that_they_replay() {
    let d = dir();
    let path = d.path().join("nan.mcap");
    let mut bad = request(3, 1);
    bad.ego.v_mps = f64::NAN;
    bad.road.speed_limit_mps = f64::INFINITY;
    bad.svs
        .push(SvObservation::new(7, 20.0, 3.5, f64::NEG_INFINITY, f64::NAN))
        .expect("room for an SV");
    let recorder = PlanRecorder::start(&RecorderOptions::new(&path)).expect("recorder");
    let reply = recorder.wrap_reply(&bad, Instant::now(), |_| {});
    reply(response(3, 1));
    recorder.finish().expect("finished");
    // serde_json alone writes `null`, which no f64 reads back.
    let raw = read_messages(&path).expect("read");
    let text = String::from_utf8(raw[0].data.clone()).expect("utf-8");
    assert!(
        text.contains(r#""v_mps":"NaN""#) && text.contains(r#""speed_limit_mps":"inf""#),
        "{text}"
    );
    let exchanges = read_exchanges(std::slice::from_ref(&path)).expect("a NaN request reads back");
    let got = &exchanges.exchanges[0];
    assert!(got.request.ego.v_mps.is_nan());
    assert_eq!(got.request.road.speed_limit_mps, f64::INFINITY);
    let sv = &got.request.svs.as_slice()[0];
    assert_eq!(sv.v_mps, f64::NEG_INFINITY);
    assert!(sv.a_mps2.is_nan());
    // Everything else is as recorded (NaN != NaN: compare with the NaNs cleared).
    let clear = |r: &PlanRequest| {
        let mut r = r.clone();
        r.ego.v_mps = 0.0;
        r.svs.as_mut_slice()[0].a_mps2 = 0.0;
        r
    };
    assert_eq!(clear(&got.request), clear(&bad));
    assert_eq!(got.response, Some(response(3, 1)));
}
