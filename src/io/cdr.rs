//! Little-endian CDR, as ROS 2 messages are written: the MCAP out's topics
//! and the Foxglove numbers.

/// A little-endian CDR message under construction.
pub(crate) struct Cdr(pub(crate) Vec<u8>);

impl Cdr {
    pub(crate) fn new() -> Self {
        Self(vec![0, 1, 0, 0])
    }

    pub(crate) fn align(&mut self, size: usize) {
        while !(self.0.len() - 4).is_multiple_of(size) {
            self.0.push(0);
        }
    }

    pub(crate) fn u8(&mut self, v: u8) -> &mut Self {
        self.0.push(v);
        self
    }

    pub(crate) fn u32(&mut self, v: u32) -> &mut Self {
        self.align(4);
        self.0.extend(v.to_le_bytes());
        self
    }

    pub(crate) fn i32(&mut self, v: i32) -> &mut Self {
        self.align(4);
        self.0.extend(v.to_le_bytes());
        self
    }

    pub(crate) fn f64(&mut self, v: f64) -> &mut Self {
        self.align(8);
        self.0.extend(v.to_le_bytes());
        self
    }

    pub(crate) fn string(&mut self, s: &str) -> &mut Self {
        self.u32(s.len() as u32 + 1);
        self.0.extend(s.as_bytes());
        self.0.push(0);
        self
    }

    pub(crate) fn header(&mut self, stamp_ns: i64, frame_id: &str) -> &mut Self {
        let sec = stamp_ns.div_euclid(1_000_000_000);
        let nanosec = stamp_ns.rem_euclid(1_000_000_000);
        self.i32(i32::try_from(sec).unwrap_or(i32::MAX))
            .u32(nanosec as u32)
            .string(frame_id)
    }

    pub(crate) fn xyz(&mut self, v: [f64; 3]) -> &mut Self {
        self.f64(v[0]).f64(v[1]).f64(v[2])
    }

    pub(crate) fn floats(&mut self, v: &[f64]) -> &mut Self {
        self.u32(v.len() as u32);
        for &x in v {
            self.f64(x);
        }
        self
    }
}
