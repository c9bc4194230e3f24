//! Mitsuba 3 scene files: reading XML (`element`), Mitsuba's semantics (`load`), the
//! resulting description (`description`) and `<transform>` math (`transform`).

pub mod description;
pub mod element;
pub mod load;
pub mod transform;

pub use description::SceneDescription;
pub use load::{load_file, LoadOptions};
