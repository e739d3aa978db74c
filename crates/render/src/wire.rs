//! One wire format for everything a frame method hands from one process to another or leaves
//! on disk: task results, pass artifacts, step inputs and frame checkpoints.
//!
//! ```text
//! "TSWF" | u16 version | u32 n | n bytes of JSON header (what the payload is, e.g. which task)
//! chunk* : u32 raw length (1..=CHUNK) | u32 compressed length | zstd(raw bytes)
//! end    : u32 0 | u64 payload length | u32 CRC-32 of the header and the raw payload
//! ```
//!
//! The payload is one value serialised with postcard. Writing and reading are streams of
//! chunks of at most [`CHUNK`] bytes, so neither side holds more than one chunk of encoded
//! bytes besides the value itself; a truncated, corrupted or foreign stream, or one of another
//! version, is refused with an error that says which.

use std::io::{self, Read, Write};

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use crate::film::{SampleRange, Tile};

/// The format's version: a reader refuses any other.
pub const VERSION: u16 = 2;
const MAGIC: &[u8; 4] = b"TSWF";
/// Most uncompressed payload bytes per chunk.
pub const CHUNK: usize = 1 << 20;
/// Largest header, bytes.
const MAX_HEADER: usize = 1 << 16;
/// zstd's level: fast; float data gains little from more effort.
const LEVEL: i32 = 1;

#[derive(Debug, thiserror::Error)]
pub enum WireError {
    #[error("expected a Tessera wire stream starting with \"TSWF\"")]
    Magic,
    #[error(
        "wire format version {got}, expected {VERSION} (written by another version of Tessera)"
    )]
    Version { got: u16 },
    #[error("cut short in {0}")]
    Truncated(&'static str),
    #[error("corrupt: {0}")]
    Corrupt(String),
    #[error("payload: {0}")]
    Payload(String),
    #[error("{0}")]
    Io(#[from] io::Error),
}

/// What a stream holds, readable without decoding its payload.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// `result`, `artifact`, `input` or `checkpoint`.
    pub what: String,
    /// The payload's type: its method or pass and the payload's version (`bdpt/1`).
    pub schema: String,
    /// The task a result is of.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub task: Option<TaskSpec>,
}

impl Header {
    pub fn new(what: &str, schema: &str) -> Self {
        Header {
            what: what.into(),
            schema: schema.into(),
            task: None,
        }
    }
}

/// Sizes of a written stream.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Sizes {
    /// The serialised payload, before compression.
    pub payload: u64,
    /// The whole stream as written.
    pub written: u64,
}

/// Writes a stream: the header at once, then the payload written through it in chunks.
pub struct Writer<W: Write> {
    out: W,
    buf: Vec<u8>,
    compressed: Vec<u8>,
    zstd: zstd::bulk::Compressor<'static>,
    crc: crc32fast::Hasher,
    sizes: Sizes,
}

impl<W: Write> Writer<W> {
    pub fn new(mut out: W, header: &Header) -> Result<Self, WireError> {
        let json = serde_json::to_vec(header).map_err(|e| WireError::Payload(e.to_string()))?;
        if json.len() > MAX_HEADER {
            return Err(WireError::Payload(format!(
                "header of {} bytes, at most {MAX_HEADER}",
                json.len()
            )));
        }
        out.write_all(MAGIC)?;
        out.write_all(&VERSION.to_le_bytes())?;
        out.write_all(&(json.len() as u32).to_le_bytes())?;
        out.write_all(&json)?;
        let mut crc = crc32fast::Hasher::new();
        crc.update(&json);
        Ok(Writer {
            out,
            buf: Vec::with_capacity(CHUNK),
            compressed: Vec::new(),
            zstd: zstd::bulk::Compressor::new(LEVEL)?,
            crc,
            sizes: Sizes {
                payload: 0,
                written: (10 + json.len()) as u64,
            },
        })
    }

    fn flush_chunk(&mut self) -> io::Result<()> {
        if self.buf.is_empty() {
            return Ok(());
        }
        self.compressed.clear();
        self.compressed
            .reserve(zstd::zstd_safe::compress_bound(self.buf.len()));
        self.zstd
            .compress_to_buffer(&self.buf, &mut self.compressed)?;
        self.out.write_all(&(self.buf.len() as u32).to_le_bytes())?;
        self.out
            .write_all(&(self.compressed.len() as u32).to_le_bytes())?;
        self.out.write_all(&self.compressed)?;
        self.sizes.written += 8 + self.compressed.len() as u64;
        self.buf.clear();
        Ok(())
    }

    /// Ends the stream; returns the writer and the sizes.
    pub fn finish(mut self) -> Result<(W, Sizes), WireError> {
        self.flush_chunk()?;
        self.out.write_all(&0u32.to_le_bytes())?;
        self.out.write_all(&self.sizes.payload.to_le_bytes())?;
        self.out
            .write_all(&self.crc.clone().finalize().to_le_bytes())?;
        self.out.flush()?;
        self.sizes.written += 16;
        Ok((self.out, self.sizes))
    }
}

impl<W: Write> Write for Writer<W> {
    fn write(&mut self, data: &[u8]) -> io::Result<usize> {
        let n = data.len().min(CHUNK - self.buf.len());
        self.buf.extend_from_slice(&data[..n]);
        self.crc.update(&data[..n]);
        self.sizes.payload += n as u64;
        if self.buf.len() == CHUNK {
            self.flush_chunk()?;
        }
        Ok(n)
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// Writes `value` as a whole stream.
pub fn write<W: Write, T: Serialize + ?Sized>(
    out: W,
    header: &Header,
    value: &T,
) -> Result<(W, Sizes), WireError> {
    let mut w = Writer::new(out, header)?;
    postcard::to_io(value, &mut w).map_err(|e| WireError::Payload(e.to_string()))?;
    w.finish()
}

/// Writes `value` into the payload of a stream being written (after other values, say).
pub fn encode_into<T: Serialize + ?Sized>(
    value: &T,
    payload: &mut dyn Write,
) -> Result<(), WireError> {
    postcard::to_io(value, payload).map_err(|e| WireError::Payload(e.to_string()))?;
    Ok(())
}

/// `value` as a stream in memory.
pub fn to_vec<T: Serialize + ?Sized>(header: &Header, value: &T) -> Result<Vec<u8>, WireError> {
    Ok(write(Vec::new(), header, value)?.0)
}

fn read_exact(r: &mut impl Read, buf: &mut [u8], what: &'static str) -> Result<(), WireError> {
    r.read_exact(buf).map_err(|e| match e.kind() {
        io::ErrorKind::UnexpectedEof => WireError::Truncated(what),
        _ => WireError::Io(e),
    })
}

/// Reads a stream: the header at once, then the payload through [`Read`] in chunks, checked
/// against the trailer's length and CRC when the last chunk has been read.
pub struct Reader<R: Read> {
    inp: R,
    chunk: Vec<u8>,
    compressed: Vec<u8>,
    at: usize,
    zstd: zstd::bulk::Decompressor<'static>,
    crc: crc32fast::Hasher,
    payload: u64,
    ended: bool,
}

impl<R: Read> Reader<R> {
    pub fn new(mut inp: R) -> Result<(Self, Header), WireError> {
        let mut head = [0u8; 10];
        read_exact(&mut inp, &mut head[..4], "the header")?;
        if &head[..4] != MAGIC {
            return Err(WireError::Magic);
        }
        read_exact(&mut inp, &mut head[4..], "the header")?;
        let got = u16::from_le_bytes([head[4], head[5]]);
        if got != VERSION {
            return Err(WireError::Version { got });
        }
        let n = u32::from_le_bytes([head[6], head[7], head[8], head[9]]) as usize;
        if n > MAX_HEADER {
            return Err(WireError::Corrupt(format!("a header of {n} bytes")));
        }
        let mut json = vec![0u8; n];
        read_exact(&mut inp, &mut json, "the header")?;
        let header: Header = serde_json::from_slice(&json)
            .map_err(|e| WireError::Corrupt(format!("header: {e}")))?;
        let mut crc = crc32fast::Hasher::new();
        crc.update(&json);
        let reader = Reader {
            inp,
            chunk: Vec::new(),
            compressed: Vec::new(),
            at: 0,
            zstd: zstd::bulk::Decompressor::new()?,
            crc,
            payload: 0,
            ended: false,
        };
        Ok((reader, header))
    }

    /// Reads the next chunk (or the trailer); false at the end.
    fn next_chunk(&mut self) -> Result<bool, WireError> {
        if self.ended {
            return Ok(false);
        }
        let mut len = [0u8; 4];
        read_exact(&mut self.inp, &mut len, "a chunk")?;
        let raw = u32::from_le_bytes(len) as usize;
        if raw == 0 {
            let mut end = [0u8; 12];
            read_exact(&mut self.inp, &mut end, "the trailer")?;
            let total = u64::from_le_bytes(end[..8].try_into().unwrap_or_default());
            let crc = u32::from_le_bytes(end[8..].try_into().unwrap_or_default());
            self.ended = true;
            if total != self.payload {
                return Err(WireError::Corrupt(format!(
                    "the trailer says {total} payload bytes, the chunks held {}",
                    self.payload
                )));
            }
            if crc != self.crc.clone().finalize() {
                return Err(WireError::Corrupt("CRC-32 mismatch".into()));
            }
            return Ok(false);
        }
        read_exact(&mut self.inp, &mut len, "a chunk")?;
        let packed = u32::from_le_bytes(len) as usize;
        if raw > CHUNK || packed > zstd::zstd_safe::compress_bound(CHUNK) {
            return Err(WireError::Corrupt(format!(
                "a chunk of {raw} bytes ({packed} compressed), at most {CHUNK}"
            )));
        }
        self.compressed.resize(packed, 0);
        read_exact(&mut self.inp, &mut self.compressed, "a chunk")?;
        self.chunk.clear();
        self.chunk.reserve(raw);
        let n = self
            .zstd
            .decompress_to_buffer(&self.compressed, &mut self.chunk)
            .map_err(|e| WireError::Corrupt(format!("a chunk does not decompress: {e}")))?;
        if n != raw {
            return Err(WireError::Corrupt(format!(
                "a chunk of {n} bytes where its length says {raw}"
            )));
        }
        self.crc.update(&self.chunk);
        self.payload += raw as u64;
        self.at = 0;
        Ok(true)
    }

    /// Payload bytes read so far (all of them once [`Self::finish`] succeeded).
    pub fn payload_len(&self) -> u64 {
        self.payload
    }

    /// Reads the payload to its end without decoding it and checks the trailer: the stream is
    /// whole and uncorrupted. Returns the payload's length.
    pub fn verify(mut self) -> Result<u64, WireError> {
        self.at = self.chunk.len();
        while self.next_chunk()? {
            self.at = self.chunk.len();
        }
        Ok(self.payload)
    }

    /// Checks that the payload was read to its end and the trailer matches; returns the
    /// underlying reader.
    pub fn finish(mut self) -> Result<R, WireError> {
        if self.at < self.chunk.len() || self.next_chunk()? {
            return Err(WireError::Corrupt(
                "payload bytes left after the value".into(),
            ));
        }
        Ok(self.inp)
    }
}

impl<R: Read> Read for Reader<R> {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        while self.at == self.chunk.len() {
            match self.next_chunk() {
                Ok(true) => {}
                Ok(false) => return Ok(0),
                Err(WireError::Io(e)) => return Err(e),
                Err(e) => return Err(io::Error::new(io::ErrorKind::InvalidData, e)),
            }
        }
        let n = out.len().min(self.chunk.len() - self.at);
        out[..n].copy_from_slice(&self.chunk[self.at..self.at + n]);
        self.at += n;
        Ok(n)
    }
}

/// An error from reading the payload through [`Reader`]: the stream's own error where it was
/// one, else the payload's.
fn payload_error(e: postcard::Error, reader_error: Option<io::Error>) -> WireError {
    if let Some(e) = reader_error {
        if let Some(inner) = e.get_ref().and_then(|i| i.downcast_ref::<WireError>()) {
            return WireError::Corrupt(match inner {
                WireError::Truncated(w) => format!("cut short in {w}"),
                other => other.to_string(),
            });
        }
        return WireError::Io(e);
    }
    WireError::Payload(format!("{e} (the payload is not what its header says)"))
}

/// Reads a value from the payload of a stream (a [`Reader`] after its header); the caller
/// then checks the end with [`Reader::finish`].
pub fn decode_from<T: DeserializeOwned>(payload: &mut dyn Read) -> Result<T, WireError> {
    let mut tracked = Tracked {
        inner: payload,
        error: None,
    };
    let mut scratch = [0u8; 256];
    match postcard::from_io::<T, _>((&mut tracked, &mut scratch)) {
        Ok((v, _)) => Ok(v),
        Err(e) => Err(payload_error(e, tracked.error.take())),
    }
}

/// Reads the payload of a stream whose header was read, to its end.
pub fn read_payload<R: Read, T: DeserializeOwned>(
    mut reader: Reader<R>,
) -> Result<(T, R), WireError> {
    let value = decode_from(&mut reader)?;
    Ok((value, reader.finish()?))
}

/// Reads a whole stream.
pub fn read<R: Read, T: DeserializeOwned>(inp: R) -> Result<(Header, T), WireError> {
    let (reader, header) = Reader::new(inp)?;
    let (value, _) = read_payload(reader)?;
    Ok((header, value))
}

/// A reader that keeps the last I/O error (postcard reports its own kind of error instead).
struct Tracked<'a> {
    inner: &'a mut dyn Read,
    error: Option<io::Error>,
}

impl Read for Tracked<'_> {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        match self.inner.read(out) {
            Ok(n) => Ok(n),
            Err(e) => {
                let copy = io::Error::new(e.kind(), e.to_string());
                self.error = Some(e);
                Err(copy)
            }
        }
    }
}

/// A unit of work of a frame or of a pass: what it computes, where it folds, and the pixels
/// and index range it covers. Methods give the fields their meaning; the farm stores, leases
/// and orders tasks by them without knowing it.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct TaskSpec {
    /// What the task computes, in its method's words (`tile`, `aov`, `photons`, …).
    pub kind: String,
    /// The frame (from 1), or 0 for a pass's task.
    pub frame: u32,
    /// The frame's step (an adaptive round, an SPPM iteration), or the pass's position in
    /// the job's list of passes.
    pub step: u32,
    /// Position in fold order within the step (or pass).
    pub index: u32,
    /// Pixels [x0, x1) × [y0, y1) it covers (empty for a pass's task).
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
    /// Index range [start, end): samples, iterations, photons, points or chains.
    pub start: u32,
    pub end: u32,
}

impl TaskSpec {
    /// A task covering no pixels and an empty range.
    pub fn new(kind: &str, frame: u32, step: u32, index: u32) -> Self {
        TaskSpec {
            kind: kind.into(),
            frame,
            step,
            index,
            x0: 0,
            y0: 0,
            x1: 0,
            y1: 0,
            start: 0,
            end: 0,
        }
    }

    pub fn with_rect(mut self, t: Tile) -> Self {
        (self.x0, self.y0, self.x1, self.y1) = (t.x0, t.y0, t.x1, t.y1);
        self
    }

    pub fn with_range(mut self, start: u32, end: u32) -> Self {
        (self.start, self.end) = (start, end);
        self
    }

    pub fn tile(&self) -> Tile {
        Tile {
            x0: self.x0,
            y0: self.y0,
            x1: self.x1.max(self.x0),
            y1: self.y1.max(self.y0),
        }
    }

    pub fn samples(&self) -> SampleRange {
        SampleRange {
            start: self.start,
            end: self.end.max(self.start),
        }
    }

    /// Pixels it covers.
    pub fn pixels(&self) -> u64 {
        self.tile().pixel_count() as u64
    }

    /// An estimate of its work: pixels × samples, or the items of its range.
    pub fn work(&self) -> u64 {
        self.pixels().max(1) * self.samples().len().max(1) as u64
    }

    /// Whether this is a pass's task.
    pub fn is_pass(&self) -> bool {
        self.frame == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> (Header, Vec<[f32; 3]>) {
        let mut h = Header::new("result", "test/1");
        h.task = Some(TaskSpec::new("tile", 1, 0, 3));
        // Several chunks of poorly compressible floats.
        let v = (0..300_000u32)
            .map(|i| {
                let x = (i as f32 * 0.618_034).fract();
                [x, x * 7.0, -x]
            })
            .collect();
        (h, v)
    }

    #[test]
    fn round_trips_across_chunks() {
        let (h, v) = sample();
        let (bytes, sizes) = write(Vec::new(), &h, &v).expect("encode");
        assert!(sizes.payload > 3 * CHUNK as u64, "{sizes:?}");
        assert_eq!(sizes.written, bytes.len() as u64);
        let (back_h, back): (Header, Vec<[f32; 3]>) = read(bytes.as_slice()).expect("decode");
        assert_eq!((back_h, back), (h, v));
    }

    #[test]
    fn truncation_corruption_and_versions_are_refused() {
        let (h, v) = sample();
        let bytes = to_vec(&h, &v).expect("encode");
        let decode = |b: &[u8]| read::<_, Vec<[f32; 3]>>(b).map(|_| ()).unwrap_err();
        // Cut anywhere: never a value.
        for cut in [3, 9, 20, bytes.len() / 2, bytes.len() - 13, bytes.len() - 1] {
            let e = decode(&bytes[..cut]);
            assert!(e.to_string().contains("cut short"), "cut at {cut}: {e}");
        }
        // A flipped bit in a compressed chunk or in the trailer's CRC.
        for at in [bytes.len() / 3, bytes.len() - 2] {
            let mut bad = bytes.clone();
            bad[at] ^= 0x10;
            let e = decode(&bad);
            assert!(e.to_string().contains("corrupt"), "flip at {at}: {e}");
        }
        let mut old = bytes.clone();
        old[4] = 9;
        assert!(matches!(
            read::<_, Vec<[f32; 3]>>(old.as_slice()),
            Err(WireError::Version { got: 9 })
        ));
        assert!(matches!(
            read::<_, Vec<[f32; 3]>>(&b"PNG\x89...."[..]),
            Err(WireError::Magic)
        ));
        // A payload of another type than the reader expects.
        let e = read::<_, (String, u64)>(bytes.as_slice()).unwrap_err();
        assert!(
            matches!(e, WireError::Payload(_) | WireError::Corrupt(_)),
            "{e}"
        );
        // Bytes after the value are refused too.
        let two = to_vec(&h, &(vec![[1.0f32; 3]], 5u8)).expect("encode");
        let e = read::<_, Vec<[f32; 3]>>(two.as_slice()).unwrap_err();
        assert!(e.to_string().contains("left after"), "{e}");
    }
}
