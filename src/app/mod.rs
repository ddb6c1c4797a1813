//! Application layer: the commands of the `relief` binary over the library, one room a file.
//!
//! * [`args`]: command-line value parsers and the render toggles several commands share;
//! * [`bench`](mod@bench): `relief bench MODE`: the benchmark modes, one report and JSON schema for all;
//! * [`capture`]: `relief render`: headless frames (pinhole, display channel, dome master);
//! * [`channel`]: a display configuration's channel by index, with the error that says so;
//! * [`cigi_ig`]: the CIGI IG of the frame loops: socket, session, ownship camera, answers;
//! * [`db`]: `relief db build|info`: the terrain database compiler and its report;
//! * [`figures`]: median, percentile, slope, memory window, resident set size;
//! * [`gpu_options`]: `--kernels` and `--trace-passes`, and the adapter opened with them;
//! * [`heap`]: the C heap over long runs: large blocks mapped, and given back when freed;
//! * [`output`]: the file writers (PNG, depth TIFF, JSON, a frame's files all or nothing);
//! * [`paged`]: `--terrain-memory`: a database scene through the paged tile pool;
//! * [`pattern_rig`]: the warp test pattern rendered through ray tables;
//! * [`sampling`]: bilinear sampling of RGBA8 images;
//! * [`scenes`]: the demo scenes in `terrains/`, found at run time;
//! * [`serve`]: `relief serve`: the headless CIGI image generator;
//! * [`two_pass`]: two-pass warping (`render --two-pass`) and the virtual views it builds on;
//! * [`upload`]: a [`crate::world::World`] put on the GPU (a renderer holding it);
//! * [`verify`]: `relief warp verify`: the closed-loop check of a display configuration;
//! * [`view`]: `relief view`: the window, its frame loop, motion and statistics;
//! * [`voxels`]: `relief voxels convert`: voxel models to the segment format;
//! * [`warp`]: `relief warp inspect|apply|export`: warp files and dome masters.

pub mod args;
pub mod bench;
pub mod capture;
pub mod channel;
pub mod cigi_ig;
pub mod db;
pub mod figures;
pub mod gpu_options;
pub mod heap;
pub mod output;
pub mod paged;
pub mod pattern_rig;
pub mod quality;
pub mod sampling;
pub mod scenes;
pub mod serve;
pub mod two_pass;
pub mod upload;
pub mod verify;
pub mod view;
pub mod voxels;
pub mod warp;
