//! Chunk decompression shared by the recording containers (MCAP, ROS 1
//! bags): bounded by the size the chunk declares, and checked against it.

use std::io::Read as _;

/// The most bytes one chunk may hold once uncompressed.
pub const MAX_CHUNK_BYTES: u64 = 1 << 30;

/// A chunk compression both containers may use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Compression {
    /// LZ4 frames.
    Lz4,
    /// Zstandard.
    Zstd,
}

/// `data` decompressed: exactly `size` bytes, or why not.
pub fn inflate(compression: Compression, data: &[u8], size: u64) -> Result<Vec<u8>, String> {
    if size > MAX_CHUNK_BYTES {
        return Err(format!("a chunk claims {size} bytes uncompressed"));
    }
    let out = match compression {
        Compression::Zstd => zstd::bulk::decompress(data, size as usize).map_err(|e| format!("zstd chunk: {e}"))?,
        Compression::Lz4 => {
            let mut out = Vec::with_capacity(size as usize);
            // One byte more than declared, to tell a longer chunk.
            lz4::Decoder::new(data)
                .and_then(|d| d.take(size + 1).read_to_end(&mut out))
                .map_err(|e| format!("lz4 chunk: {e}"))?;
            out
        }
    };
    if out.len() as u64 == size {
        Ok(out)
    } else {
        Err(format!(
            "a chunk holds {} bytes uncompressed, its header says {size}",
            out.len()
        ))
    }
}
