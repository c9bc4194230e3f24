//! Which ray caster traverses a scene's triangles: Embree 3 where it is installed and
//! pays (see [`super::embree_api`] for `MEDIAREG_ACCEL`), else obvhs.

use super::embree_api;

/// Below this many triangles in the BVH, obvhs traverses them even where Embree is
/// asked for: on the corpus's Cornell boxes (12 and 38 triangles) Embree's renders took
/// 1.1–1.3× obvhs's, on a 2,256-triangle teapot 0.87× (docs/performance.md).
pub const EMBREE_MIN_TRIANGLES: usize = 1024;

/// Which ray caster traverses the triangles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    /// obvhs's compressed wide BVH, with this module's node and triangle tests.
    Obvhs,
    /// Embree 3, when it loads (else obvhs). It is used where the BVH would hold
    /// triangles only, at least [`EMBREE_MIN_TRIANGLES`] of them: fewer stay obvhs's
    /// (or are tested one by one), and a BVH that holds analytic shapes too (more than
    /// [`super::build::SEPARATE_ANALYTIC`]) stays obvhs's.
    Embree,
}

impl Backend {
    /// What `MEDIAREG_ACCEL` asks for (see [`embree_api`]): unset, Embree when it loads,
    /// else obvhs; an error for a value it does not know or for `embree` where the
    /// library does not load.
    pub fn requested() -> Result<Backend, String> {
        use embree_api::Request;
        match embree_api::request()? {
            Request::Obvhs => Ok(Backend::Obvhs),
            Request::Auto => Ok(match embree_api::load() {
                Ok(_) => Backend::Embree,
                Err(_) => Backend::Obvhs,
            }),
            Request::Embree => match embree_api::load() {
                Ok(_) => Ok(Backend::Embree),
                Err(e) => Err(format!(
                    "MEDIAREG_ACCEL=embree: Embree 3 does not load ({e}); {}",
                    embree_api::INSTALL_HINT
                )),
            },
        }
    }

    /// The ray caster a render of a triangle mesh uses, as `mediareg --version` says it:
    /// Embree (its version and file) or obvhs, with why where Embree is not used.
    pub fn describe() -> String {
        match Backend::requested() {
            Ok(Backend::Embree) => match embree_api::load() {
                Ok(api) => format!(
                    "Embree {} ({}) for meshes of {EMBREE_MIN_TRIANGLES} triangles or more",
                    api.version, api.path
                ),
                Err(e) => format!("obvhs (Embree: {e})"),
            },
            Ok(Backend::Obvhs) => match embree_api::load() {
                Ok(_) => "obvhs (MEDIAREG_ACCEL=obvhs)".to_string(),
                Err(e) => format!(
                    "obvhs (Embree 3 does not load: {e}; for the faster one, {})",
                    embree_api::INSTALL_HINT
                ),
            },
            Err(e) => format!("obvhs ({e})"),
        }
    }
}
