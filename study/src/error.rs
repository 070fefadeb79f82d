//! What can go wrong in a study: a file that cannot be written or read, a render that
//! fails, a figure that does not draw, a sweep run that exits with an error.

use std::path::PathBuf;

/// An error of the accuracy study or the sweep; the message names the file or run.
#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    /// A file or folder of the study could not be created, written or read.
    #[error("cannot {action} {}: {reason}", path.display())]
    Io {
        /// What was tried: "create", "write", "read".
        action: &'static str,
        /// The file or folder.
        path: PathBuf,
        /// The operating system's reason.
        reason: std::io::Error,
    },
    /// A CSV table could not be encoded.
    #[error("cannot write the CSV table {}: {reason}", path.display())]
    Csv {
        /// The table's file (empty when it is built in memory).
        path: PathBuf,
        /// The encoder's reason.
        reason: csv::Error,
    },
    /// A scene setting of the study does not preprocess.
    #[error(transparent)]
    Prepare(#[from] magg_core::prepared::PrepareError),
    /// A render of the study failed.
    #[error(transparent)]
    Render(#[from] magg_core::machine::RenderError),
    /// The sweep's hardware profile does not load.
    #[error(transparent)]
    Profile(#[from] magg_throttle::ProfileError),
    /// The application's image writer refused a frame of the study.
    #[error("cannot write image {}: {reason}", path.display())]
    Image {
        /// The image file.
        path: PathBuf,
        /// The writer's reason.
        reason: String,
    },
    /// A figure could not be drawn or encoded.
    #[error("cannot draw a figure: {0}")]
    Plot(String),
    /// A sweep run could not start, failed, or left no readable stats.
    #[error("sweep run {run}: {reason}")]
    Run {
        /// The run's shape.
        run: String,
        /// What went wrong (its last line of stderr when it failed).
        reason: String,
    },
}

impl StudyError {
    /// An [`StudyError::Io`] for `path`.
    pub fn io(action: &'static str, path: impl Into<PathBuf>) -> impl FnOnce(std::io::Error) -> StudyError {
        let path = path.into();
        move |reason| StudyError::Io { action, path, reason }
    }
}

/// A study's result.
pub type Result<T, E = StudyError> = std::result::Result<T, E>;
