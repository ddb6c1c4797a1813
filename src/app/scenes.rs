//! The demo scenes shipped in `terrains/`, found at run time: what `relief` renders with no
//! command, and what each `relief bench` mode measures when no scene is given.

use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// The scene `relief` renders when run without a command.
pub const DEFAULT_SCENE: &str = "terrains/alps.toml";

/// Finds the shipped file `relative` (such as [`DEFAULT_SCENE`]): in the current directory,
/// next to the executable, then two levels above it (cargo's `target/<profile>/relief` in a
/// source tree). The error lists the places searched and says to pass a scene file.
pub fn find_shipped(relative: &str) -> Result<PathBuf> {
    let mut places = vec![PathBuf::from(relative)];
    if let Ok(exe) = std::env::current_exe() {
        let dir = exe.parent();
        places.extend(dir.map(|d| d.join(relative)));
        let tree = dir.and_then(Path::parent).and_then(Path::parent);
        places.extend(tree.map(|d| d.join(relative)));
    }
    if let Some(found) = places.iter().find(|p| p.is_file()) {
        return Ok(found.clone());
    }
    // The first place as the absolute path it stands for.
    if let Ok(cwd) = std::env::current_dir() {
        places[0] = cwd.join(relative);
    }
    let searched: Vec<String> = places.iter().map(|p| p.display().to_string()).collect();
    Err(Error::invalid(
        "scene",
        format!(
            "no scene file given, and the default {relative} is in none of the places searched ({}): pass a scene file, e.g. `relief render SCENE.toml`",
            searched.join(", ")
        ),
    ))
}
