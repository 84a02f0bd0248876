//! # dfsph-io — exports for dfsph2d
//!
//! Writers for the files `dfsph2d run` produces, all built on the solver's public API
//! ([`dfsph::Snapshot`], [`dfsph::StepStats`]):
//!
//! - [`csv`]: particle snapshots (`x,y,vx,vy,density,pressure`) and the frame index
//!   (`frame,time,file`), and the rigid bodies' poses and velocities
//!   (`frame,time,body,x,y,angle,vx,vy,omega`);
//! - [`stats`]: one row of [`dfsph::StepStats`] per step;
//! - [`vtk`]: VTK XML UnstructuredGrid (`.vtu`) snapshots that ParaView opens, and a `.pvd`
//!   collection that gives ParaView the frame times; the rigid bodies' outlines as polygon
//!   cells;
//! - [`render`]: a CPU rasteriser (tiny-skia) that draws a frame to PNG, fluid coloured by
//!   speed with a [`colormap`] and a legend, rigid bodies as filled outlines coloured by
//!   density (as the interactive viewer draws them);
//! - [`video`]: those frames, stamped with their simulated time, as an animated GIF (pure
//!   Rust) or an MP4 (through `ffmpeg`), playing at simulated speed.
//!
//! - [`numbers`]: how times and statistics are written (no digits beyond what the solver's
//!   single precision and the clock's sums resolve).
//!
//! - [`input`]: the scene a SCENE argument names (a built-in name or a JSON file), files read
//!   with a size limit, and the checks on output paths, with one-line messages.
//!
//! Snapshots and other whole files are written atomically ([`atomic`]): to `NAME.tmp` in the
//! same directory, synced, then renamed, so a reader never sees a half-written file. Files that
//! grow during a run (statistics, the frame index) are appended one complete line at a time
//! ([`append`]), so a run stopped at any point keeps everything it completed.

pub mod append;
pub mod atomic;
pub mod colormap;
pub mod csv;
mod font;
pub mod input;
pub mod numbers;
pub mod render;
pub mod stats;
pub mod surface;
pub mod video;
pub mod vtk;

pub use append::AppendFile;
pub use atomic::{write_atomic, AtomicFile};
pub use csv::{
    bodies_csv_rows, frame_index_row, write_frame_index, write_snapshot_csv, FrameRecord,
    BODIES_HEADER, INDEX_HEADER, SNAPSHOT_HEADER,
};
pub use render::{render_frame, write_png, RenderGeometry, RenderOptions};
pub use stats::{StatsCsvWriter, STATS_HEADER};
pub use vtk::{write_bodies_vtu, write_pvd, write_vtu, write_walls_vtu};
