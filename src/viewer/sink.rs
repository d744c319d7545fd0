//! Where a recording goes: an `.rrd` file, or a running Rerun viewer over gRPC.

use std::path::PathBuf;

use anyhow::{anyhow, Result};
use rerun::{RecordingStream, RecordingStreamBuilder};

/// Where to send what is logged.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Sink {
    /// Write an `.rrd` file.
    Save(PathBuf),
    /// Stream to the viewer at this URL (`rerun+http://HOST:PORT/proxy`).
    Connect(String),
}

/// The URL of a viewer started with `rerun` on this machine.
pub const DEFAULT_URL: &str = rerun::DEFAULT_CONNECT_URL;

impl Sink {
    /// From `--save FILE` or `--connect [URL]` (`--save` wins; neither: an error).
    pub fn from_args(save: Option<&PathBuf>, connect: Option<&String>) -> Result<Self> {
        match (save, connect) {
            (Some(path), _) => Ok(Sink::Save(path.clone())),
            (None, Some(url)) => Ok(Sink::Connect(url.clone())),
            (None, None) => Err(anyhow!("give --save FILE.rrd or --connect [URL]")),
        }
    }

    /// Opens a recording of application `app` on this sink.
    pub fn open(&self, app: &'static str) -> Result<RecordingStream> {
        let builder = RecordingStreamBuilder::new(app);
        match self {
            Sink::Save(path) => builder
                .save(path)
                .map_err(|e| anyhow!("cannot write {}: {}", path.display(), root_cause(&e))),
            Sink::Connect(url) => builder
                .connect_grpc_opts(url.clone())
                .map_err(|e| anyhow!("cannot connect to the Rerun viewer at {url}: {}", root_cause(&e))),
        }
    }
}

/// The innermost error of a chain (Rerun's repeat the path at every level).
fn root_cause(e: &dyn std::error::Error) -> String {
    let mut e = e;
    while let Some(source) = e.source() {
        e = source;
    }
    e.to_string()
}

/// Sends what is still buffered; a failure is reported, not fatal (the data logged so
/// far stays usable).
pub fn finish(rec: &RecordingStream) {
    if let Err(e) = rec.flush_blocking() {
        tracing::warn!("rerun: cannot flush the recording: {e}");
    }
}
