//! A synchronous MCAP writer with fixed channels and rotation.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use crate::error::{RecordingError, Result};

/// One channel of a recording: a topic carrying JSON messages of one schema.
#[derive(Debug, Clone)]
pub struct ChannelSpec {
    /// Topic, e.g. `/planner/request`.
    pub topic: &'static str,
    /// Schema name, e.g. `hmdp.PlanRequest` or `foxglove.SceneUpdate` (Foxglove recognises
    /// its own schemas by name).
    pub schema_name: &'static str,
    /// The JSON Schema.
    pub schema: fn() -> serde_json::Value,
}

/// When a long recording starts a new file.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Rotation {
    /// After about this many bytes of messages.
    pub max_bytes: Option<u64>,
    /// After this long (wall time).
    pub max_duration: Option<Duration>,
}

/// The open file of a [`McapSink`].
struct OpenFile {
    writer: mcap::Writer<BufWriter<File>>,
    /// Channel ids, in the order of the sink's channels.
    channel_ids: Vec<u16>,
    bytes: u64,
    opened: Instant,
}

/// Writes messages to `FILE.mcap`; with rotation the following files are `FILE.1.mcap`,
/// `FILE.2.mcap`, ... each a complete MCAP file with every channel.
pub struct McapSink {
    base: PathBuf,
    channels: Vec<ChannelSpec>,
    rotation: Rotation,
    file: Option<OpenFile>,
    files: Vec<PathBuf>,
    sequence: u32,
    messages: u64,
}

/// Bytes a message adds besides its payload (record header, channel, sequence, times).
const MESSAGE_OVERHEAD: u64 = 1 + 8 + 2 + 4 + 8 + 8;

impl McapSink {
    /// Creates `path` (and its directory) with `channels`.
    pub fn create(path: &Path, channels: Vec<ChannelSpec>, rotation: Rotation) -> Result<Self> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|e| RecordingError::io(dir, e))?;
        }
        let mut sink = Self {
            base: path.to_owned(),
            channels,
            rotation,
            file: None,
            files: Vec::new(),
            sequence: 0,
            messages: 0,
        };
        sink.open_next()?;
        Ok(sink)
    }

    /// The index of the channel with `topic`.
    pub fn channel(&self, topic: &str) -> Option<usize> {
        self.channels.iter().position(|c| c.topic == topic)
    }

    /// Path of the `index`-th file.
    fn path_of(&self, index: usize) -> PathBuf {
        if index == 0 {
            return self.base.clone();
        }
        let stem = self
            .base
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        self.base.with_file_name(format!("{stem}.{index}.mcap"))
    }

    fn open_next(&mut self) -> Result<()> {
        let path = self.path_of(self.files.len());
        let file = File::create(&path).map_err(|e| RecordingError::io(&path, e))?;
        let options = mcap::WriteOptions::new()
            .compression(None)
            .profile("")
            .library(concat!("hmdp-recording/", env!("CARGO_PKG_VERSION")));
        let mut writer = options
            .create(BufWriter::new(file))
            .map_err(|e| RecordingError::mcap(&path, e))?;
        let mut channel_ids = Vec::with_capacity(self.channels.len());
        for c in &self.channels {
            let schema = serde_json::to_vec(&(c.schema)()).map_err(|source| RecordingError::Encode {
                topic: c.topic.to_owned(),
                source,
            })?;
            let schema_id = writer
                .add_schema(c.schema_name, "jsonschema", &schema)
                .map_err(|e| RecordingError::mcap(&path, e))?;
            let id = writer
                .add_channel(schema_id, c.topic, "json", &BTreeMap::new())
                .map_err(|e| RecordingError::mcap(&path, e))?;
            channel_ids.push(id);
        }
        self.files.push(path);
        self.file = Some(OpenFile {
            writer,
            channel_ids,
            bytes: 0,
            opened: Instant::now(),
        });
        Ok(())
    }

    fn close_current(&mut self) -> Result<()> {
        if let Some(mut f) = self.file.take() {
            let path = self.files.last().cloned().unwrap_or_default();
            f.writer.finish().map_err(|e| RecordingError::mcap(&path, e))?;
        }
        Ok(())
    }

    fn rotation_due(&self, f: &OpenFile) -> bool {
        f.bytes > 0
            && (self.rotation.max_bytes.is_some_and(|max| f.bytes >= max)
                || self.rotation.max_duration.is_some_and(|max| f.opened.elapsed() >= max))
    }

    /// Writes one message (already JSON) on channel `channel` at `log_time_ns`.
    pub fn write(&mut self, channel: usize, log_time_ns: u64, publish_time_ns: u64, data: &[u8]) -> Result<()> {
        if self.file.as_ref().is_some_and(|f| self.rotation_due(f)) {
            self.close_current()?;
            self.open_next()?;
        }
        let path = self.files.last().cloned().unwrap_or_default();
        let Some(f) = self.file.as_mut() else {
            return Err(RecordingError::WriterGone);
        };
        let Some(&channel_id) = f.channel_ids.get(channel) else {
            return Err(RecordingError::mcap(
                &path,
                mcap::McapError::UnknownChannel(self.sequence, channel as u16),
            ));
        };
        let header = mcap::records::MessageHeader {
            channel_id,
            sequence: self.sequence,
            log_time: log_time_ns,
            publish_time: publish_time_ns,
        };
        f.writer
            .write_to_known_channel(&header, data)
            .map_err(|e| RecordingError::mcap(&path, e))?;
        f.bytes += data.len() as u64 + MESSAGE_OVERHEAD;
        self.sequence = self.sequence.wrapping_add(1);
        self.messages += 1;
        Ok(())
    }

    /// Serialises `value` as JSON (non-finite floats as strings, see [`crate::json`]) and
    /// writes it.
    pub fn write_json<T: serde::Serialize + ?Sized>(
        &mut self,
        channel: usize,
        log_time_ns: u64,
        value: &T,
    ) -> Result<()> {
        let data = crate::json::to_vec(value).map_err(|source| RecordingError::Encode {
            topic: self.channels.get(channel).map_or("?", |c| c.topic).to_owned(),
            source,
        })?;
        self.write(channel, log_time_ns, log_time_ns, &data)
    }

    /// Messages written so far.
    pub fn messages(&self) -> u64 {
        self.messages
    }

    /// Writes the summaries and closes the file; returns every file written.
    pub fn finish(mut self) -> Result<Vec<PathBuf>> {
        self.close_current()?;
        Ok(std::mem::take(&mut self.files))
    }
}

impl Drop for McapSink {
    fn drop(&mut self) {
        // A sink dropped without `finish` (an error path) still leaves a readable file.
        let _ = self.close_current();
    }
}
