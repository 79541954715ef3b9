//! Tests of [`super`]: `rosmsg.rs`.

use super::*;

const JOINT_STATE_ROS2: &str = "# a comment\nstd_msgs/Header header\n\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n\
================================================================================\nMSG: std_msgs/Header\n# Standard metadata\nbuiltin_interfaces/Time stamp\nstring frame_id\n\
================================================================================\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n";

/// Hand-encoded CDR of a `JointState`: stamp 5 s + 7 ns, frame `b`,
/// names `a1, a2`, position `1.5, -2`, no velocity, effort `0.25`.
fn joint_state_cdr() -> Vec<u8> {
    let mut b = vec![0, 1, 0, 0];
    b.extend(5i32.to_le_bytes());
    b.extend(7u32.to_le_bytes());
    b.extend(2u32.to_le_bytes()); // "b\0"
    b.extend(b"b\0");
    b.extend([0, 0]); // align to 4
    b.extend(2u32.to_le_bytes());
    b.extend(3u32.to_le_bytes());
    b.extend(b"a1\0");
    b.push(0); // align
    b.extend(3u32.to_le_bytes());
    b.extend(b"a2\0");
    b.push(0); // align to 4 for the length
    b.extend(2u32.to_le_bytes());
    // Offset from the origin is now 40: aligned for the float64s.
    b.extend(1.5f64.to_le_bytes());
    b.extend((-2.0f64).to_le_bytes());
    b.extend(0u32.to_le_bytes());
    b.extend(1u32.to_le_bytes());
    b.extend(0.25f64.to_le_bytes());
    b
}

#[test]
fn decodes_a_hand_encoded_cdr_joint_state() {
    let def = MessageDefinition::parse("sensor_msgs/msg/JointState", JOINT_STATE_ROS2, Encoding::Cdr).unwrap();
    assert_eq!(def.name(), "sensor_msgs/JointState");
    let bytes = joint_state_cdr();
    let value = def.decode(&bytes).unwrap();
    assert_eq!(value.get("header.stamp.sec").and_then(Value::as_i64), Some(5));
    assert_eq!(value.get("header.stamp.nanosec").and_then(Value::as_i64), Some(7));
    assert_eq!(value.get("header.frame_id"), Some(&Value::Str("b".into())));
    assert_eq!(
        value.get("name").and_then(Value::as_strings),
        Some(vec!["a1".into(), "a2".into()])
    );
    assert_eq!(value.get("position").and_then(Value::as_floats), Some(vec![1.5, -2.0]));
    assert_eq!(value.get("velocity").and_then(Value::as_floats), Some(vec![]));
    assert_eq!(value.get("effort").and_then(Value::as_floats), Some(vec![0.25]));
    assert_eq!(value.float_array_paths(), vec!["position", "velocity", "effort"]);
    // Every shorter prefix is an error, never a panic or a wrong value.
    for n in 0..bytes.len() {
        assert!(def.decode(&bytes[..n]).is_err(), "prefix of {n} bytes decoded");
    }
}

#[test]
fn big_endian_cdr_reads_the_same() {
    let def = MessageDefinition::parse("pkg/msg/T", "int16 a\nfloat64 b\nuint32[2] c", Encoding::Cdr).unwrap();
    let mut b = vec![0, 0, 0, 0];
    b.extend((-3i16).to_be_bytes());
    b.extend([0; 6]);
    b.extend(2.5f64.to_be_bytes());
    b.extend(9u32.to_be_bytes());
    b.extend(10u32.to_be_bytes());
    let v = def.decode(&b).unwrap();
    assert_eq!(v.get("a").and_then(Value::as_i64), Some(-3));
    assert_eq!(v.get("b").and_then(Value::as_f64), Some(2.5));
    assert_eq!(v.get("c"), Some(&Value::List(vec![Value::UInt(9), Value::UInt(10)])));
}

#[test]
fn ros1_has_no_alignment_no_terminators_and_a_time_type() {
    let text = "Header header\nstring[] name\nfloat64[] effort\n\
================================================================================\nMSG: std_msgs/Header\nuint32 seq\ntime stamp\nstring frame_id\n";
    let def = MessageDefinition::parse("sensor_msgs/JointState", text, Encoding::Ros1).unwrap();
    let mut b = Vec::new();
    b.extend(3u32.to_le_bytes());
    b.extend(10u32.to_le_bytes());
    b.extend(20u32.to_le_bytes());
    b.extend(1u32.to_le_bytes());
    b.extend(b"w");
    b.extend(1u32.to_le_bytes());
    b.extend(2u32.to_le_bytes());
    b.extend(b"j1");
    b.extend(1u32.to_le_bytes());
    b.extend(4.0f64.to_le_bytes());
    let v = def.decode(&b).unwrap();
    assert_eq!(v.get("header.seq").and_then(Value::as_i64), Some(3));
    assert_eq!(v.get("header.stamp.sec").and_then(Value::as_i64), Some(10));
    assert_eq!(v.get("header.stamp.nanosec").and_then(Value::as_i64), Some(20));
    assert_eq!(v.get("header.frame_id"), Some(&Value::Str("w".into())));
    assert_eq!(v.get("name").and_then(Value::as_strings), Some(vec!["j1".into()]));
    assert_eq!(v.get("effort").and_then(Value::as_floats), Some(vec![4.0]));
}

#[test]
fn constants_comments_defaults_and_bounds_are_understood() {
    let text = "int8 MODE_A=0 # trailing\nstring NAME = x # y\nint8 mode # the mode\nfloat64[7] q\nstring<=8 label\nint32[<=3] few\nfloat64 gain 1.5\n";
    let def = MessageDefinition::parse("vendor/msg/State", text, Encoding::Cdr).unwrap();
    let mut b = vec![0, 1, 0, 0, 2];
    b.extend([0; 7]);
    for i in 0..7 {
        b.extend(f64::from(i).to_le_bytes());
    }
    b.extend(3u32.to_le_bytes());
    b.extend(b"ok\0");
    b.push(0);
    b.extend(1u32.to_le_bytes());
    b.extend((-4i32).to_le_bytes());
    b.extend(1.5f64.to_le_bytes());
    let v = def.decode(&b).unwrap();
    assert_eq!(v.get("mode").and_then(Value::as_i64), Some(2));
    assert_eq!(
        v.get("q").and_then(Value::as_floats),
        Some((0..7).map(f64::from).collect())
    );
    assert_eq!(v.get("label"), Some(&Value::Str("ok".into())));
    assert_eq!(v.get("few"), Some(&Value::List(vec![Value::Int(-4)])));
    assert_eq!(v.get("gain").and_then(Value::as_f64), Some(1.5));
}

#[test]
fn bad_definitions_and_messages_are_errors() {
    assert!(matches!(
        MessageDefinition::parse("a/B", "foo/Bar x", Encoding::Cdr),
        Err(MsgError::UnknownType { .. })
    ));
    assert!(matches!(
        MessageDefinition::parse("a/B", "float64[x] q", Encoding::Cdr),
        Err(MsgError::Definition { .. })
    ));
    // A type that contains itself.
    let looped = "a/B b\n===\nMSG: a/B\na/B b";
    assert!(MessageDefinition::parse("a/B", looped, Encoding::Cdr).is_err());
    // A sequence claiming more elements than there are bytes.
    let def = MessageDefinition::parse("a/B", "float64[] q", Encoding::Cdr).unwrap();
    let mut b = vec![0, 1, 0, 0];
    b.extend(u32::MAX.to_le_bytes());
    assert!(matches!(def.decode(&b), Err(MsgError::Invalid { .. })));
    assert!(matches!(def.decode(&[1, 2, 3, 4]), Err(MsgError::Invalid { .. })));
}
