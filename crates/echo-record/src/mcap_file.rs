//! MCAP writing and reading for Echo's messages.
//!
//! Every key expression becomes one channel (`topic` = the key, `message_encoding` = `json`,
//! no schema: the JSON is self-describing and versioned by its header). `log_time` is the
//! recorder's receive time (ns since the Unix epoch); `publish_time` is the sender's
//! `header.stamp_ns` when the payload has one, else the receive time.

use std::collections::{BTreeMap, HashMap};
use std::io::{Seek, Write};
use std::path::{Path, PathBuf};

/// Errors reading or writing a recording.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The file could not be opened, read or written.
    #[error("{path}: {source}")]
    Io {
        /// The recording.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The MCAP structure is invalid (truncated, bad magic, bad record).
    #[error("{path}: not a valid MCAP file: {source}")]
    Mcap {
        /// The recording.
        path: PathBuf,
        /// What the MCAP library reported.
        source: mcap::McapError,
    },
    /// Writing failed inside the MCAP library.
    #[error("writing MCAP: {0}")]
    Write(#[from] mcap::McapError),
}

/// One recorded message.
#[derive(Debug, Clone, PartialEq)]
pub struct Recorded {
    /// The key expression it arrived on.
    pub key: String,
    /// Receive time at the recorder, ns since the Unix epoch.
    pub log_time_ns: u64,
    /// The sender's stamp (`header.stamp_ns`) or the receive time.
    pub publish_time_ns: u64,
    /// The payload, unchanged.
    pub payload: Vec<u8>,
}

/// Writes messages to an MCAP file, one channel per key.
pub struct Recorder<W: Write + Seek> {
    writer: mcap::Writer<W>,
    channels: HashMap<String, u16>,
    sequences: HashMap<u16, u32>,
    count: u64,
}

impl<W: Write + Seek> Recorder<W> {
    /// A recorder writing to `w` (uncompressed chunks, with the summary and indexes readers use).
    pub fn new(w: W) -> Result<Self, RecordingError> {
        let writer = mcap::WriteOptions::new()
            .compression(None)
            .profile("")
            .library(concat!("echo-record ", env!("CARGO_PKG_VERSION")))
            .create(w)?;
        Ok(Recorder {
            writer,
            channels: HashMap::new(),
            sequences: HashMap::new(),
            count: 0,
        })
    }

    /// Record `payload` received on `key` at `log_time_ns`.
    pub fn write(
        &mut self,
        key: &str,
        log_time_ns: u64,
        payload: &[u8],
    ) -> Result<(), RecordingError> {
        let channel_id = match self.channels.get(key) {
            Some(id) => *id,
            None => {
                let id = self.writer.add_channel(0, key, "json", &BTreeMap::new())?;
                self.channels.insert(key.to_string(), id);
                id
            }
        };
        let seq = self.sequences.entry(channel_id).or_insert(0);
        *seq = seq.wrapping_add(1);
        let header = mcap::records::MessageHeader {
            channel_id,
            sequence: *seq,
            log_time: log_time_ns,
            publish_time: sender_stamp(payload).unwrap_or(log_time_ns),
        };
        self.writer.write_to_known_channel(&header, payload)?;
        self.count += 1;
        Ok(())
    }

    /// Messages written so far.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// Write the summary and end the file.
    pub fn finish(mut self) -> Result<W, RecordingError> {
        self.writer.finish()?;
        Ok(self.writer.into_inner())
    }
}

/// `header.stamp_ns` of a JSON payload, if it has one.
fn sender_stamp(payload: &[u8]) -> Option<u64> {
    #[derive(serde::Deserialize)]
    struct Stamped {
        header: StampOnly,
    }
    #[derive(serde::Deserialize)]
    struct StampOnly {
        stamp_ns: u64,
    }
    serde_json::from_slice::<Stamped>(payload)
        .ok()
        .map(|s| s.header.stamp_ns)
}

/// Read every bus message (the `json` channels) of the recording at `path`, in log-time order.
/// Channels in other encodings — what viewers derive from the bus, such as Foxglove scenes —
/// are skipped.
pub fn read_recording(path: &Path) -> Result<Vec<Recorded>, RecordingError> {
    let bytes = std::fs::read(path).map_err(|source| RecordingError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mcap_err = |source| RecordingError::Mcap {
        path: path.to_path_buf(),
        source,
    };
    let mut out = vec![];
    for m in mcap::MessageStream::new(&bytes).map_err(mcap_err)? {
        let m = m.map_err(mcap_err)?;
        if m.channel.message_encoding != "json" {
            continue;
        }
        out.push(Recorded {
            key: m.channel.topic.clone(),
            log_time_ns: m.log_time,
            publish_time_ns: m.publish_time,
            payload: m.data.into_owned(),
        });
    }
    out.sort_by_key(|r| r.log_time_ns);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_keeps_keys_times_and_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.mcap");
        let mut rec = Recorder::new(std::io::BufWriter::new(
            std::fs::File::create(&path).unwrap(),
        ))
        .unwrap();
        let a = br#"{"header":{"stamp_ns":7},"x":1}"#;
        rec.write("echo/r1/humans", 100, a).unwrap();
        rec.write("echo/r1/robot/state", 150, b"not json").unwrap();
        rec.write("echo/r1/humans", 200, a).unwrap();
        assert_eq!(rec.count(), 3);
        rec.finish().unwrap();
        let back = read_recording(&path).unwrap();
        assert_eq!(back.len(), 3);
        assert_eq!(back[0].key, "echo/r1/humans");
        assert_eq!(back[0].publish_time_ns, 7);
        assert_eq!(back[1].key, "echo/r1/robot/state");
        assert_eq!(back[1].publish_time_ns, 150);
        assert_eq!(back[1].payload, b"not json");
        assert_eq!(back[2].log_time_ns, 200);
    }

    #[test]
    fn derived_channels_are_skipped() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("viewer.mcap");
        let file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
        let mut w = mcap::WriteOptions::new()
            .compression(None)
            .create(file)
            .unwrap();
        let schema = w
            .add_schema("foxglove.SceneUpdate", "protobuf", b"x")
            .unwrap();
        let scene = w
            .add_channel(schema, "/scene", "protobuf", &BTreeMap::new())
            .unwrap();
        let bus = w
            .add_channel(0, "echo/r1/humans", "json", &BTreeMap::new())
            .unwrap();
        for (channel_id, data) in [(scene, &b"\x0a\x00"[..]), (bus, &b"{}"[..])] {
            let header = mcap::records::MessageHeader {
                channel_id,
                sequence: 1,
                log_time: 5,
                publish_time: 5,
            };
            w.write_to_known_channel(&header, data).unwrap();
        }
        w.finish().unwrap();
        drop(w);
        let back = read_recording(&path).unwrap();
        assert_eq!(back.len(), 1);
        assert_eq!(back[0].key, "echo/r1/humans");
    }

    #[test]
    fn truncated_and_foreign_files_are_named_errors() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.mcap");
        std::fs::write(&path, b"\x89MCAP0\r\nrubbish").unwrap();
        let e = read_recording(&path).unwrap_err().to_string();
        assert!(e.contains("bad.mcap") && e.contains("MCAP"), "{e}");
        let e = read_recording(&dir.path().join("missing.mcap"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing.mcap"), "{e}");
    }
}
