//! The bytes RustDDS puts on the wire for our messages are those rclpy (rosidl's Fast CDR
//! typesupport) writes for the same message, encapsulation header included; and rclpy's
//! bytes decode into the same message. rclpy builds its message from the JSON of ours
//! (serde_json, ROS field names). Needs the ROS 2 venv (`scripts/ros2-env`).
//!
//! Fast CDR does not write its alignment padding (those bytes keep whatever the buffer
//! held), so rclpy also prints which bytes are padding, found by walking the message with
//! rosidl's field types and CDR's alignment rules in Python: every other byte must be equal,
//! and ours are zero there.

mod common;

use hmdp_ros2::msg;
use ros2_client::dds::rustdds::no_key::SerializerAdapter;
use ros2_client::dds::rustdds::serialization::{deserialize_from_cdr_with_rep_id, to_writer_with_rep_id};
use ros2_client::dds::rustdds::{CDRSerializerAdapter, RepresentationIdentifier, SerializedPayload};
use serde::de::DeserializeOwned;
use serde::Serialize;

/// Builds the message from its JSON (stdin) and prints its CDR as rclpy serialises it,
/// then the padding mask (`d` data, `p` padding) of that CDR.
const SERIALIZE: &str = r#"
from rclpy.serialization import serialize_message
SIZES = {'boolean': 1, 'octet': 1, 'char': 1, 'int8': 1, 'uint8': 1, 'int16': 2, 'uint16': 2,
         'int32': 4, 'uint32': 4, 'float': 4, 'int64': 8, 'uint64': 8, 'double': 8}

def walk(message, mask):
    """Marks the bytes `message` occupies as data, aligning as CDR does (to the element's
    size, counted from the start of the body)."""
    for key, type_name in message.get_fields_and_field_types().items():
        value = getattr(message, key)
        if type_name.startswith('sequence<'):
            data(mask, 4)
            element = type_name[len('sequence<'):-1].split(',')[0]
            for item in value:
                one(item, element, mask)
        elif type_name.endswith(']'):
            element = type_name[:type_name.index('[')]
            for item in value:
                one(item, element, mask)
        else:
            one(value, type_name, mask)

def one(value, type_name, mask):
    if type_name in SIZES:
        data(mask, SIZES[type_name])
    elif type_name.startswith('string'):
        data(mask, 4)
        mask.extend('d' * (len(value.encode()) + 1))
    else:
        walk(value, mask)

def data(mask, size):
    mask.extend('p' * (-len(mask) % size))
    mask.extend('d' * size)

kind, document = sys.argv[1], json.load(sys.stdin)
if kind == 'Plan_Request':
    from hmdp_msgs.srv import Plan
    message = Plan.Request(request=fill(message_class('hmdp_msgs/PlanRequest')(), document))
elif kind == 'MarkerArray':
    message = fill(message_class('visualization_msgs/MarkerArray')(), document)
else:
    message = fill(message_class('hmdp_msgs/' + kind)(), document)
print(serialize_message(message).hex())
mask = []
walk(message, mask)
print('dddd' + ''.join(mask))
"#;

/// rclpy's CDR of the message `json` describes, and its padding mask.
fn rclpy_cdr(kind: &str, json: &str) -> (Vec<u8>, String) {
    let script = format!("{}{SERIALIZE}", common::PY_MESSAGES);
    let out = common::python(&script, &[kind], json, &[]);
    assert!(
        out.status.success(),
        "rclpy could not serialise {kind}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).expect("text");
    let mut lines = text.lines();
    let hex = lines.next().expect("the CDR");
    let mask = lines.next().expect("the padding mask").to_owned();
    let bytes = (0..hex.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&hex[i..i + 2], 16).expect("hex digits"))
        .collect();
    (bytes, mask)
}

/// What a topic writer (`/hmdp/decisions`) puts in a DATA submessage: the encapsulation
/// header and the CDR of `CDRSerializerAdapter`.
fn topic_payload<M: Serialize>(message: &M) -> Vec<u8> {
    let body = CDRSerializerAdapter::<M>::to_bytes(message).expect("serialises");
    wire(body.to_vec())
}

/// What the service writers put there: the CDR of `to_writer_with_rep_id` (Enhanced
/// mapping, no header of its own).
fn service_payload<M: Serialize>(message: &M) -> Vec<u8> {
    let mut body = Vec::new();
    to_writer_with_rep_id(&mut body, message, RepresentationIdentifier::CDR_LE).expect("serialises");
    wire(body)
}

fn wire(body: Vec<u8>) -> Vec<u8> {
    let payload = SerializedPayload::new(RepresentationIdentifier::CDR_LE, body);
    payload.bytes_slice(0, payload.len_serialized()).to_vec()
}

/// Ours equal rclpy's on every data byte, and are zero on the padding.
fn assert_same_cdr(what: &str, ours: &[u8], json: &str, kind: &str) {
    let (theirs, mask) = rclpy_cdr(kind, json);
    assert_eq!(
        ours.len(),
        theirs.len(),
        "{what}: length\nours  {ours:02x?}\nrclpy {theirs:02x?}"
    );
    assert_eq!(mask.len(), theirs.len(), "{what}: the walk covers the message");
    assert_eq!(
        &ours[..4],
        &[0x00, 0x01, 0x00, 0x00],
        "{what}: CDR little endian encapsulation"
    );
    for (i, ((&o, &t), m)) in ours.iter().zip(&theirs).zip(mask.bytes()).enumerate() {
        if m == b'd' {
            assert_eq!(o, t, "{what}: byte {i}\nours  {ours:02x?}\nrclpy {theirs:02x?}");
        } else {
            assert_eq!(o, 0, "{what}: padding byte {i} is not zero in ours");
        }
    }
}

/// rclpy's bytes decode into `expected` with the decoder RustDDS uses.
fn assert_decodes<M: DeserializeOwned + PartialEq + std::fmt::Debug>(what: &str, expected: &M, json: &str, kind: &str) {
    let (bytes, _) = rclpy_cdr(kind, json);
    let (decoded, _) =
        deserialize_from_cdr_with_rep_id::<M>(&bytes[4..], RepresentationIdentifier::CDR_LE).expect("decodes");
    assert_eq!(&decoded, expected, "{what}");
}

#[test]
fn the_worked_example_request_is_byte_identical() {
    let request = common::worked_example(7, 42);
    let message = msg::PlanRequest::from(&request);
    let json = serde_json::to_string(&message).unwrap();
    assert_same_cdr("PlanRequest", &topic_payload(&message), &json, "PlanRequest");
    let service_request = msg::PlanServiceRequest::from(&request);
    assert_eq!(service_payload(&service_request), topic_payload(&message));
    assert_same_cdr(
        "Plan_Request",
        &service_payload(&service_request),
        &json,
        "Plan_Request",
    );
    assert_decodes("PlanRequest", &message, &json, "PlanRequest");
}

#[test]
fn a_request_with_corrective_entries_and_many_svs_is_byte_identical() {
    let mut request = common::worked_example(9, 1);
    let sv = request.svs[0];
    let svs: Vec<_> = (0..64)
        .map(|id| protocol::SvObservation {
            id,
            x_m: f64::from(id) * 7.5 - 100.0,
            ..sv
        })
        .collect();
    request.svs = protocol::bounded("svs", &svs).unwrap();
    let entries: Vec<_> = (0..16)
        .map(|id| protocol::CorrectiveEntry {
            sv_id: id,
            release_m: 40.0 + f64::from(id),
            trigger_m: 30.0,
        })
        .collect();
    request.memory.corrective = protocol::bounded("memory.corrective", &entries).unwrap();
    let message = msg::PlanRequest::from(&request);
    let json = serde_json::to_string(&message).unwrap();
    assert_same_cdr("full PlanRequest", &topic_payload(&message), &json, "PlanRequest");
    assert_decodes("full PlanRequest", &message, &json, "PlanRequest");
}

#[test]
fn a_decided_response_is_byte_identical() {
    let response = common::canned_decision(7, 42);
    let message = msg::PlanResponse::from(&response);
    let json = serde_json::to_string(&message).unwrap();
    assert_same_cdr("decided PlanResponse", &topic_payload(&message), &json, "PlanResponse");
    assert_decodes("decided PlanResponse", &message, &json, "PlanResponse");
}

#[test]
fn a_rejected_response_is_byte_identical() {
    let response = common::canned_rejection(7, 43);
    let message = msg::PlanResponse::from(&response);
    let json = serde_json::to_string(&message).unwrap();
    assert_same_cdr("rejected PlanResponse", &topic_payload(&message), &json, "PlanResponse");
    assert_decodes("rejected PlanResponse", &message, &json, "PlanResponse");
}

#[test]
fn the_markers_are_byte_identical_to_kilted_visualization_msgs() {
    let request = common::worked_example(7, 42);
    let stamp = msg::viz::Time {
        sec: 1_767_225_600,
        nanosec: 123_456_789,
    };
    let markers = hmdp_ros2::markers::plan_markers(&request, &common::canned_decision(7, 42), stamp);
    let json = serde_json::to_string(&markers).unwrap();
    assert_same_cdr("MarkerArray", &topic_payload(&markers), &json, "MarkerArray");
    assert_decodes("MarkerArray", &markers, &json, "MarkerArray");
}

/// `clients/ros2/hmdp_ros2_client.py cdr` (the project's rclpy client: its own conversion
/// from the protocol's JSON form, padding zeroed) gives our bytes exactly.
fn python_client_cdr(kind: &str, json: &str) -> Vec<u8> {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/../../../clients/ros2/hmdp_ros2_client.py");
    let out = std::process::Command::new(common::venv().join("bin/python"))
        .args([script, "cdr", kind])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .and_then(|mut child| {
            use std::io::Write;
            child.stdin.take().expect("piped").write_all(json.as_bytes())?;
            child.wait_with_output()
        })
        .expect("the python client runs");
    assert!(
        out.status.success(),
        "hmdp_ros2_client.py cdr {kind}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).expect("text");
    let hex = text.trim().trim_matches('"');
    (0..hex.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&hex[i..i + 2], 16).expect("hex digits"))
        .collect()
}

#[test]
fn the_python_clients_cdr_of_the_protocol_json_form_is_ours() {
    let request = common::worked_example(7, 42);
    assert_eq!(
        python_client_cdr("PlanRequest", &protocol::encode_json(&request)),
        topic_payload(&msg::PlanRequest::from(&request))
    );
    for response in [common::canned_decision(7, 42), common::canned_rejection(7, 43)] {
        assert_eq!(
            python_client_cdr("PlanResponse", &protocol::encode_json(&response)),
            topic_payload(&msg::PlanResponse::from(&response))
        );
    }
}
