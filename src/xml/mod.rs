//! Mitsuba 3 scene files: reading XML (`element`), Mitsuba's semantics (`load`), the
//! resulting description (`description`), `<transform>` math (`transform`), references
//! to objects declared later (`refs`), the upgrade of files older than 2.0 (`upgrade`,
//! with 0.6's medium presets in `media_presets`) and where file names are looked for
//! (`resolve`).

pub mod description;
pub mod element;
pub mod load;
pub mod media_presets;
pub mod refs;
pub mod resolve;
pub mod transform;
pub mod upgrade;

pub use description::SceneDescription;
pub use load::{load_file, LoadOptions};
