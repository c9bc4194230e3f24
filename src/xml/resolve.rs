//! Mitsuba's `FileResolver`: where a file name in a scene is looked for.

use std::path::{Path, PathBuf};

/// Resolves a relative file name like Mitsuba's file resolver: the scene's folder first,
/// then each `-a` folder in order. Absolute names are taken as they are.
pub fn resolve_path(search_path: &[PathBuf], name: &str) -> Option<PathBuf> {
    let p = Path::new(name);
    if p.is_absolute() {
        return p.exists().then(|| p.to_path_buf());
    }
    search_path.iter().map(|d| d.join(p)).find(|c| c.exists())
}
