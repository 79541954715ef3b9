//! Tests of the recordings' readers.

use super::frames::*;
use super::*;

#[test]
fn bag_messages_become_topics() {
    let bag = crate::io::bag::tests::tiny_bag(&[(1_000_000_000, 1.0), (1_100_000_000, 2.0), (1_200_000_000, 3.0)]);
    let index = index(Path::new("x.bag"), &bag).unwrap();
    assert_eq!(index.container, "ROS 1 bag");
    let [topic] = index.topics.as_slice() else { panic!() };
    assert_eq!(topic.topic, "/x");
    assert_eq!(topic.message_type, "std_msgs/Float64");
    assert_eq!(topic.count, 3);
    assert!((topic.rate_hz().unwrap() - 10.0).abs() < 1e-9);
    assert_eq!(
        topic.first.as_ref().and_then(|v| v.get("data")).and_then(Value::as_f64),
        Some(1.0)
    );
    assert_eq!(topic.stamp_source(), StampSource::LogTime);
    // Nothing to make frames of.
    assert!(matches!(
        index.mapping(&TopicChoice::default()),
        Err(RecordingError::Choice { .. })
    ));
}

/// Found by the fuzzer: a record inside a chunk claiming 2^64 - 1
/// bytes made the `mcap` crate's chunk reader overflow (a panic).
#[test]
fn a_chunk_record_claiming_exabytes_is_an_error() {
    let mut file = MCAP_MAGIC.to_vec();
    let record = |op: u8, body: &[u8]| {
        let mut r = vec![op];
        r.extend((body.len() as u64).to_le_bytes());
        r.extend(body);
        r
    };
    // Header: profile "", library "".
    file.extend(record(0x01, &[0; 8]));
    let mut inner = vec![0xff];
    inner.extend(u64::MAX.to_le_bytes());
    let mut chunk = Vec::new();
    chunk.extend(0u64.to_le_bytes());
    chunk.extend(0u64.to_le_bytes());
    chunk.extend((inner.len() as u64).to_le_bytes());
    chunk.extend(0u32.to_le_bytes());
    chunk.extend(0u32.to_le_bytes()); // compression "": none
    chunk.extend((inner.len() as u64).to_le_bytes());
    chunk.extend(&inner);
    file.extend(record(0x06, &chunk));
    let result = index(Path::new("x.mcap"), &file);
    assert!(
        matches!(result, Err(RecordingError::Mcap { .. })),
        "{:?}",
        result.map(|i| i.topics.len())
    );
}

#[test]
fn interpolation_is_exact_at_samples_and_linear_between() {
    let s = Samples {
        stamps_ns: vec![0, 10, 20],
        values: vec![0.0, 1.0, 1.0, 3.0, 2.0, 5.0],
        width: 2,
    };
    assert_eq!(s.at(10), Some(vec![1.0, 3.0]));
    assert_eq!(s.at(15), Some(vec![1.5, 4.0]));
    assert_eq!(s.at(20), Some(vec![2.0, 5.0]));
    assert_eq!(s.at(21), None);
    assert_eq!(s.at(-1), None);
}

#[test]
fn joints_are_mapped_by_name() {
    let mut order = JointOrder {
        names: Some(vec!["a".into(), "b".into(), "c".into()]),
        cached: None,
    };
    let names = |n: &[&str]| Some(n.iter().map(|s| (*s).to_owned()).collect());
    assert_eq!(
        order.arrange(names(&["c", "a", "b"]), &[3.0, 1.0, 2.0]),
        Ok(vec![1.0, 2.0, 3.0])
    );
    assert_eq!(
        order.arrange(names(&["c", "a", "b"]), &[6.0, 4.0, 5.0]),
        Ok(vec![4.0, 5.0, 6.0])
    );
    assert!(order.arrange(names(&["c", "a", "x"]), &[0.0; 3]).is_err());
    assert!(order.arrange(names(&["c", "a"]), &[0.0; 2]).is_err());
    assert!(order.arrange(None, &[0.0; 2]).is_err());
    assert_eq!(order.arrange(None, &[7.0, 8.0, 9.0]), Ok(vec![7.0, 8.0, 9.0]));
}

#[test]
fn a_message_that_names_a_joint_twice_is_refused_naming_it() {
    let names = |n: &[&str]| Some(n.iter().map(|s| (*s).to_owned()).collect());
    // As the first message (which sets the order) and after it.
    let mut fresh = JointOrder {
        names: None,
        cached: None,
    };
    let e = fresh.arrange(names(&["a", "b", "a"]), &[1.0, 2.0, 3.0]).unwrap_err();
    assert!(e.contains("'a' twice"), "{e}");
    let mut order = JointOrder {
        names: Some(vec!["a".into(), "b".into(), "c".into()]),
        cached: None,
    };
    let e = order.arrange(names(&["a", "c", "a"]), &[1.0, 2.0, 3.0]).unwrap_err();
    assert!(e.contains("'a' twice"), "{e}");
}

#[test]
fn stamps_come_from_headers_or_field_pairs() {
    let s = |fields: Vec<(&str, Value)>| Value::Struct(fields.into_iter().map(|(n, v)| (Arc::from(n), v)).collect());
    let header = s(vec![(
        "header",
        s(vec![(
            "stamp",
            s(vec![("sec", Value::Int(2)), ("nanosec", Value::UInt(5))]),
        )]),
    )]);
    assert_eq!(StampSource::of(&header).stamp_ns(&header, 0), Some(2_000_000_005));
    let fri = s(vec![
        ("sample_time", Value::Float(0.005)),
        ("time_stamp_sec", Value::UInt(3)),
        ("time_stamp_nano_sec", Value::UInt(7)),
    ]);
    assert_eq!(
        StampSource::of(&fri),
        StampSource::Fields {
            sec: "time_stamp_sec".into(),
            nanosec: "time_stamp_nano_sec".into()
        }
    );
    assert_eq!(StampSource::of(&fri).stamp_ns(&fri, 0), Some(3_000_000_007));
    let bare = s(vec![("data", Value::Float(1.0))]);
    assert_eq!(StampSource::of(&bare).stamp_ns(&bare, 42), Some(42));
}
