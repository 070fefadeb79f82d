//! Events of the host service for watchers such as the live view: which node registered,
//! took which subscreen, sent which rows, and where the host redivided a subscreen.
//!
//! The service sends them, when a watcher asked for them, on an unbounded channel: sending
//! never blocks the service and no event is lost (a watcher must keep up; the live view
//! does, it only appends to its log).

use magg_core::cluster::NodeReport;
use magg_core::subscreen::Subscreen;
use magg_proto::v1;

/// Something the host service saw (or the driver did).
#[derive(Clone, Debug)]
pub enum ClusterEvent {
    /// The viewing pass of frame `index` of `count` starts (sent by the driver, in order
    /// with the service's events, so that a watcher knows which frame rows belong to).
    FrameBegins {
        /// Frame index.
        index: usize,
        /// Frames in the render.
        count: usize,
    },
    /// A node registered.
    Registered {
        /// Its id.
        node: u32,
        /// The name it gave.
        name: String,
    },
    /// A node sent its cumulative report.
    Report {
        /// Node id.
        node: u32,
        /// The report.
        report: NodeReport,
        /// Bytes of its messages with the host so far (its link traffic).
        link_bytes: u64,
    },
    /// A node was handed subscreen `id`.
    Assigned {
        /// Node id.
        node: u32,
        /// Subscreen id (per frame).
        id: u64,
        /// Its pixels.
        rect: Subscreen,
    },
    /// Rows of subscreen `id` arrived (linear RGB, 3 floats per pixel).
    Rows {
        /// Node id.
        node: u32,
        /// Subscreen id.
        id: u64,
        /// The rows.
        rows: Vec<v1::Row>,
    },
    /// The host took back the rows of subscreen `id` from row `at` on (adaptive
    /// redivision): they become a new subscreen.
    Redivided {
        /// Subscreen id.
        id: u64,
        /// First row taken back.
        at: u32,
    },
}

/// Where the service sends its events.
pub type EventSender = tokio::sync::mpsc::UnboundedSender<ClusterEvent>;
