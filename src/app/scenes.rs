//! The demo scenes shipped in `terrains/`, found at run time: what `relief` renders with no
//! command, and what each `relief bench` mode measures when no scene is given.

use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// The scene `relief` renders when run without a command.
pub const DEFAULT_SCENE: &str = "terrains/alps.toml";

/// Finds the shipped file `relative` (such as [`DEFAULT_SCENE`]): in the current directory
/// (returned as `relative` itself), next to the executable, then two levels above it (cargo's
/// `target/<profile>/relief` in a source tree). The error lists the places searched and says to
/// pass a scene file.
pub fn find_shipped(relative: &str) -> Result<PathBuf> {
    if Path::new(relative).is_file() {
        return Ok(PathBuf::from(relative));
    }
    let mut searched: Vec<PathBuf> = Vec::new();
    let cwd =
        std::env::current_dir().map_or_else(|_| PathBuf::from(relative), |d| d.join(relative));
    searched.push(cwd);
    if let Some(dir) = std::env::current_exe()
        .ok()
        .and_then(|e| e.parent().map(Path::to_path_buf))
    {
        let tree = dir
            .parent()
            .and_then(Path::parent)
            .map(|d| d.join(relative));
        for place in [Some(dir.join(relative)), tree].into_iter().flatten() {
            if place.is_file() {
                return Ok(place);
            }
            if !searched.contains(&place) {
                searched.push(place);
            }
        }
    }
    let searched: Vec<String> = searched.iter().map(|p| p.display().to_string()).collect();
    Err(Error::invalid(
        "scene",
        format!(
            "no scene file given, and the default {relative} is in none of the places searched ({}): pass a scene file as the command's SCENE argument",
            searched.join(", ")
        ),
    ))
}
