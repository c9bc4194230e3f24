//! Embree 3, loaded at run time (`libloading`): every build can use it, and a render
//! uses it whenever the library is installed (Debian's `libembree3-3`), with no build
//! flag and no rebuild after installing it. The binding is the C functions of Embree 3's
//! API that [`super::embree`] calls, and the structures they take, as `rtcore_*.h` of
//! Embree 3 declare them for its default configuration (one instance level, no minimum
//! curve width), which Debian's and Intel's builds use.
//!
//! Which ray caster a render uses (`MEDIAREG_ACCEL`):
//! - unset: Embree when the library loads, else obvhs;
//! - `embree`: Embree, and an error naming what is missing when it does not load;
//! - `obvhs`: obvhs (the tests of both backends use this).
//!
//! Where the library is looked for: `MEDIAREG_EMBREE` (its path; when set, nowhere
//! else), else the system's library path (`libembree3.so.3`).

use std::ffi::{c_char, c_int, c_void};
use std::path::PathBuf;
use std::sync::OnceLock;

use libloading::Library;

pub type Device = *mut c_void;
pub type Scene = *mut c_void;
pub type Geometry = *mut c_void;

/// The library's soname.
const SONAME: &str = "libembree3.so.3";
/// What to install for the fast ray caster (the README's set-up).
pub const INSTALL_HINT: &str =
    "install Embree 3 (Debian/Ubuntu: apt-get install libembree3-3), or set \
MEDIAREG_EMBREE=/path/to/libembree3.so.3";

// rtcore_*.h of Embree 3: the enumerators used.
pub const BUILD_QUALITY_MEDIUM: c_int = 1;
pub const BUILD_QUALITY_HIGH: c_int = 2;
pub const SCENE_FLAG_CONTEXT_FILTER_FUNCTION: c_int = 1 << 3;
pub const GEOMETRY_TYPE_TRIANGLE: c_int = 0;
pub const BUFFER_TYPE_INDEX: c_int = 0;
pub const BUFFER_TYPE_VERTEX: c_int = 1;
pub const FORMAT_UINT3: c_int = 0x5003;
pub const FORMAT_FLOAT3: c_int = 0x9003;
pub const ERROR_NONE: c_int = 0;
pub const INTERSECT_CONTEXT_FLAG_INCOHERENT: c_int = 0;
pub const DEVICE_PROPERTY_VERSION: c_int = 0;
pub const INVALID_ID: u32 = u32::MAX;

/// `RTCRay`: a ray and its segment [tnear, tfar].
#[repr(C, align(16))]
#[derive(Clone, Copy)]
pub struct Ray {
    pub org: [f32; 3],
    pub tnear: f32,
    pub dir: [f32; 3],
    pub time: f32,
    pub tfar: f32,
    pub mask: u32,
    pub id: u32,
    pub flags: u32,
}

/// `RTCHit`: the geometric normal (not normalised), barycentrics and ids of a hit.
#[repr(C, align(16))]
#[derive(Clone, Copy)]
pub struct Hit {
    pub ng: [f32; 3],
    pub u: f32,
    pub v: f32,
    pub prim_id: u32,
    pub geom_id: u32,
    pub inst_id: [u32; 1],
}

/// `RTCRayHit`.
#[repr(C)]
#[derive(Clone, Copy)]
pub struct RayHit {
    pub ray: Ray,
    pub hit: Hit,
}

/// `RTCFilterFunctionNArguments`: N rays and hits in structure-of-arrays layout.
#[repr(C)]
pub struct FilterArguments {
    pub valid: *mut c_int,
    pub geometry_user_ptr: *mut c_void,
    pub context: *mut IntersectContext,
    pub ray: *mut c_void,
    pub hit: *mut c_void,
    pub n: u32,
}

pub type FilterFunction = unsafe extern "C" fn(*const FilterArguments);

/// `RTCIntersectContext` (one instance level, no minimum width).
#[repr(C)]
pub struct IntersectContext {
    pub flags: c_int,
    pub filter: Option<FilterFunction>,
    pub inst_id: [u32; 1],
}

impl IntersectContext {
    /// `rtcInitIntersectContext` (an inline function of the header).
    pub fn new(filter: Option<FilterFunction>) -> IntersectContext {
        IntersectContext {
            flags: INTERSECT_CONTEXT_FLAG_INCOHERENT,
            filter,
            inst_id: [INVALID_ID],
        }
    }
}

/// The functions used, resolved once.
pub struct Api {
    pub new_device: unsafe extern "C" fn(*const c_char) -> Device,
    pub release_device: unsafe extern "C" fn(Device),
    pub get_device_error: unsafe extern "C" fn(Device) -> c_int,
    pub get_device_property: unsafe extern "C" fn(Device, c_int) -> isize,
    pub new_scene: unsafe extern "C" fn(Device) -> Scene,
    pub release_scene: unsafe extern "C" fn(Scene),
    pub set_scene_build_quality: unsafe extern "C" fn(Scene, c_int),
    pub set_scene_flags: unsafe extern "C" fn(Scene, c_int),
    pub commit_scene: unsafe extern "C" fn(Scene),
    pub new_geometry: unsafe extern "C" fn(Device, c_int) -> Geometry,
    pub set_shared_geometry_buffer:
        unsafe extern "C" fn(Geometry, c_int, u32, c_int, *const c_void, usize, usize, usize),
    pub set_geometry_build_quality: unsafe extern "C" fn(Geometry, c_int),
    pub commit_geometry: unsafe extern "C" fn(Geometry),
    pub attach_geometry: unsafe extern "C" fn(Scene, Geometry) -> u32,
    pub release_geometry: unsafe extern "C" fn(Geometry),
    pub intersect1: unsafe extern "C" fn(Scene, *mut IntersectContext, *mut RayHit),
    pub occluded1: unsafe extern "C" fn(Scene, *mut IntersectContext, *mut Ray),
    /// "3.13.5".
    pub version: String,
    pub path: String,
    // Kept loaded while the pointers above point into it.
    _lib: Library,
}

fn open() -> Result<Api, String> {
    let named = std::env::var_os("MEDIAREG_EMBREE").map(PathBuf::from);
    let shown = named
        .as_ref()
        .map_or(SONAME.to_string(), |p| p.display().to_string());
    // SAFETY: loading runs Embree's initialisers (and TBB's), which are sound.
    let lib = unsafe {
        match &named {
            Some(p) => Library::new(p),
            None => Library::new(SONAME),
        }
    }
    .map_err(|e| format!("{shown}: {e}"))?;
    macro_rules! sym {
        ($name:literal) => {
            // SAFETY: the symbol's type is its declaration in Embree 3's headers.
            *unsafe { lib.get($name) }.map_err(|e| format!("{shown}: {e}"))?
        };
    }
    let mut api = Api {
        new_device: sym!(b"rtcNewDevice\0"),
        release_device: sym!(b"rtcReleaseDevice\0"),
        get_device_error: sym!(b"rtcGetDeviceError\0"),
        get_device_property: sym!(b"rtcGetDeviceProperty\0"),
        new_scene: sym!(b"rtcNewScene\0"),
        release_scene: sym!(b"rtcReleaseScene\0"),
        set_scene_build_quality: sym!(b"rtcSetSceneBuildQuality\0"),
        set_scene_flags: sym!(b"rtcSetSceneFlags\0"),
        commit_scene: sym!(b"rtcCommitScene\0"),
        new_geometry: sym!(b"rtcNewGeometry\0"),
        set_shared_geometry_buffer: sym!(b"rtcSetSharedGeometryBuffer\0"),
        set_geometry_build_quality: sym!(b"rtcSetGeometryBuildQuality\0"),
        commit_geometry: sym!(b"rtcCommitGeometry\0"),
        attach_geometry: sym!(b"rtcAttachGeometry\0"),
        release_geometry: sym!(b"rtcReleaseGeometry\0"),
        intersect1: sym!(b"rtcIntersect1\0"),
        occluded1: sym!(b"rtcOccluded1\0"),
        version: String::new(),
        path: shown.clone(),
        _lib: lib,
    };
    // SAFETY: a device is made, queried and released; a null one is checked.
    let v = unsafe {
        let device = (api.new_device)(std::ptr::null());
        if device.is_null() {
            return Err(format!("{shown}: rtcNewDevice failed"));
        }
        let v = (api.get_device_property)(device, DEVICE_PROPERTY_VERSION);
        (api.release_device)(device);
        v
    };
    // Version 3.x.y is 30000 + 100 x + y; the structures above are Embree 3's.
    if !(30000..40000).contains(&v) {
        return Err(format!("{shown} is Embree version {v}, not Embree 3"));
    }
    api.version = format!("{}.{}.{}", v / 10000, v / 100 % 100, v % 100);
    Ok(api)
}

/// Embree 3, loaded on first use, or why it could not be.
pub fn load() -> Result<&'static Api, String> {
    static LOADED: OnceLock<Result<Api, String>> = OnceLock::new();
    LOADED.get_or_init(open).as_ref().map_err(Clone::clone)
}

/// What `MEDIAREG_ACCEL` asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// Unset: Embree when it loads.
    Auto,
    Embree,
    Obvhs,
}

/// `MEDIAREG_ACCEL`, or why its value is not understood.
pub fn request() -> Result<Request, String> {
    match std::env::var("MEDIAREG_ACCEL").as_deref() {
        Err(_) | Ok("") => Ok(Request::Auto),
        Ok("embree") => Ok(Request::Embree),
        Ok("obvhs") => Ok(Request::Obvhs),
        Ok(other) => Err(format!(
            "MEDIAREG_ACCEL={other}: the ray caster is `embree` or `obvhs` (unset: Embree \
             when it is installed)"
        )),
    }
}
