//! Intel Open Image Denoise 1.4, loaded at run time (`libloading`), so that a build and
//! a render without `--denoise` never need it. The binding is the dozen C functions of
//! OIDN's API that the `RT` filter takes (`oidn.h` of 1.4): a device, a filter, images
//! shared with it, and the error query.
//!
//! Where the library is looked for, first found wins:
//! 1. `MEDIAREG_OIDN` (the library's path); when set, nowhere else.
//! 2. `.cache/oidn/` of this source tree (what `scripts/fetch_oidn` fills).
//! 3. The active Python environment's `oidn` package (`$VIRTUAL_ENV`), PyPI's `oidn`
//!    0.2.1 wheel, which ships the library and the TBB it needs.
//! 4. The system's library path (`libOpenImageDenoise.so.1`).
//!
//! Determinism: for HDR input OIDN 1.4 scales the colour by an exposure it computes
//! itself (`getAutoexposure`, core/color.cpp) with a `tbb::parallel_reduce` float sum,
//! whose order follows TBB's work stealing: the same input then gave outputs differing by
//! up to 5e-5 relative in about half of the calls of one process. The same exposure is
//! computed here, sequentially, and passed as `inputScale` ([`autoexposure`]); the rest
//! of the filter gave the same bits on repeated calls, with 1 or 2 threads
//! (`OIDN_NUM_THREADS`) and with FTZ/DAZ set on the calling thread (on AVX-512; another
//! instruction set may round differently).
//!
//! TBB: OIDN needs `libtbb.so.12`. Where a `libtbb.so.12*` lies beside the library (as in
//! the wheel) it is loaded first, so the dynamic loader finds it by its soname; else the
//! system's (Debian's `libtbb12`).

use std::ffi::{c_char, c_void, CStr, CString};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

use libloading::{Library, Symbol};

/// The library's file name in PyPI's wheel and in `scripts/fetch_oidn`'s folder.
pub const LIBRARY_FILE: &str = "libOpenImageDenoise.so.1.4.3";
/// The versions this binding was written against: 1.4.x (OIDN 2 changed the API).
const VERSION_RANGE: std::ops::Range<i32> = 10400..20000;
/// What to run to get the library (the README's set-up).
pub const INSTALL_HINT: &str =
    "run scripts/fetch_oidn (it puts PyPI's oidn 0.2.1 library in .cache/oidn), \
or set MEDIAREG_OIDN=/path/to/libOpenImageDenoise.so.1.4.3";

#[derive(Debug, Clone, PartialEq)]
pub enum OidnError {
    /// No library found, or the one named could not be loaded.
    NotFound(String),
    /// A library was loaded but is not OIDN 1.4.
    WrongLibrary(String),
    /// OIDN reported an error (its message).
    Failed(String),
    /// The input cannot be denoised (sizes, NaN or Inf, negative HDR values).
    BadInput(String),
}

impl std::fmt::Display for OidnError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            OidnError::NotFound(m) => write!(
                f,
                "Intel Open Image Denoise 1.4 was not found ({m}): {INSTALL_HINT}"
            ),
            OidnError::WrongLibrary(m) => write!(
                f,
                "{m}: mediareg needs Intel Open Image Denoise 1.4; {INSTALL_HINT}"
            ),
            OidnError::Failed(m) => write!(f, "Open Image Denoise failed: {m}"),
            OidnError::BadInput(m) => write!(f, "cannot denoise: {m}"),
        }
    }
}

impl std::error::Error for OidnError {}

type Handle = *mut c_void;
// oidn.h 1.4: OIDNDeviceType CPU = 1; OIDNFormat FLOAT3 = 3; OIDNError NONE = 0.
const DEVICE_TYPE_CPU: i32 = 1;
const FORMAT_FLOAT3: i32 = 3;

/// The functions used, resolved once.
struct Api {
    new_device: unsafe extern "C" fn(i32) -> Handle,
    commit_device: unsafe extern "C" fn(Handle),
    get_device_1i: unsafe extern "C" fn(Handle, *const c_char) -> i32,
    get_device_error: unsafe extern "C" fn(Handle, *mut *const c_char) -> i32,
    new_filter: unsafe extern "C" fn(Handle, *const c_char) -> Handle,
    #[allow(clippy::type_complexity)]
    set_shared_filter_image: unsafe extern "C" fn(
        Handle,
        *const c_char,
        *mut c_void,
        i32,
        usize,
        usize,
        usize,
        usize,
        usize,
    ),
    set_filter_1b: unsafe extern "C" fn(Handle, *const c_char, bool),
    set_filter_1f: unsafe extern "C" fn(Handle, *const c_char, f32),
    commit_filter: unsafe extern "C" fn(Handle),
    execute_filter: unsafe extern "C" fn(Handle),
    release_filter: unsafe extern "C" fn(Handle),
}

/// A loaded library with its CPU device. The device serialises its work, and so does
/// the mutex around it.
pub struct Oidn {
    api: Api,
    device: Mutex<Device>,
    version: i32,
    path: PathBuf,
    // Kept loaded while `api` points into them (TBB first, OIDN after).
    _libs: Vec<Library>,
}

/// The device and the last filter it ran, kept for the next image of the same layout:
/// committing an `RT` filter builds its network, which costs about as much as running
/// it on a small image, and a second commit with only the images' addresses changed
/// builds nothing (OIDN rebuilds where a size, format or the set of images changes).
struct Device {
    handle: Handle,
    filter: Option<(FilterLayout, Handle)>,
}

/// What a filter's network depends on.
#[derive(Clone, Copy, PartialEq)]
struct FilterLayout {
    width: usize,
    height: usize,
    albedo: bool,
    normal: bool,
    clean: bool,
}

// The device and filter handles are used only under the mutex; OIDN's API is
// thread-safe.
unsafe impl Send for Oidn {}
unsafe impl Sync for Oidn {}

/// The auxiliary images OIDN's `RT` filter takes beside the colour: the albedo and the
/// normal of what each pixel sees first (see `integrator::aovs`).
#[derive(Clone, Copy)]
pub struct Aux<'a> {
    pub albedo: &'a [[f32; 3]],
    pub normal: Option<&'a [[f32; 3]]>,
    /// The buffers are free of noise (OIDN's `cleanAux`): then it trusts their edges.
    pub clean: bool,
}

fn candidates() -> Result<Vec<PathBuf>, OidnError> {
    if let Some(p) = std::env::var_os("MEDIAREG_OIDN") {
        let p = PathBuf::from(p);
        if !p.is_file() {
            return Err(OidnError::NotFound(format!(
                "MEDIAREG_OIDN={} is not a file",
                p.display()
            )));
        }
        return Ok(vec![p]);
    }
    let mut out = vec![Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(".cache/oidn")
        .join(LIBRARY_FILE)];
    if let Some(venv) = std::env::var_os("VIRTUAL_ENV") {
        if let Ok(entries) = std::fs::read_dir(Path::new(&venv).join("lib")) {
            for e in entries.flatten() {
                out.push(
                    e.path()
                        .join("site-packages/oidn/lib.linux.x64")
                        .join(LIBRARY_FILE),
                );
            }
        }
    }
    Ok(out.into_iter().filter(|p| p.is_file()).collect())
}

/// Loads TBB from beside `lib` where it lies there (the wheel's layout).
fn bundled_tbb(lib: &Path) -> Option<Library> {
    let dir = lib.parent()?;
    let mut tbb: Vec<PathBuf> = std::fs::read_dir(dir)
        .ok()?
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("libtbb.so.12"))
        })
        .collect();
    tbb.sort();
    // SAFETY: TBB's initialisers are safe to run; it is only loaded here.
    tbb.first().and_then(|p| unsafe { Library::new(p) }.ok())
}

fn open(path: Option<&Path>) -> Result<Oidn, OidnError> {
    let mut libs = Vec::new();
    if let Some(tbb) = path.and_then(bundled_tbb) {
        libs.push(tbb);
    }
    let shown = path.map_or("libOpenImageDenoise.so.1".to_string(), |p| {
        p.display().to_string()
    });
    // SAFETY: loading runs the library's initialisers (OIDN's and TBB's, both sound).
    let lib = unsafe {
        match path {
            Some(p) => Library::new(p),
            None => Library::new("libOpenImageDenoise.so.1"),
        }
    }
    .map_err(|e| OidnError::NotFound(format!("{shown}: {e}")))?;
    macro_rules! sym {
        ($name:literal) => {{
            // SAFETY: the signature is oidn.h 1.4's for this name.
            let s: Symbol<_> =
                unsafe { lib.get(concat!($name, "\0").as_bytes()) }.map_err(|_| {
                    OidnError::WrongLibrary(format!("{shown} has no function {}", $name))
                })?;
            *s
        }};
    }
    let api = Api {
        new_device: sym!("oidnNewDevice"),
        commit_device: sym!("oidnCommitDevice"),
        get_device_1i: sym!("oidnGetDevice1i"),
        get_device_error: sym!("oidnGetDeviceError"),
        new_filter: sym!("oidnNewFilter"),
        set_shared_filter_image: sym!("oidnSetSharedFilterImage"),
        set_filter_1b: sym!("oidnSetFilter1b"),
        set_filter_1f: sym!("oidnSetFilter1f"),
        commit_filter: sym!("oidnCommitFilter"),
        execute_filter: sym!("oidnExecuteFilter"),
        release_filter: sym!("oidnReleaseFilter"),
    };
    libs.push(lib);
    // SAFETY: the functions come from the library just loaded and kept in `libs`.
    let device = unsafe { (api.new_device)(DEVICE_TYPE_CPU) };
    if device.is_null() {
        return Err(OidnError::Failed(format!("{shown}: no CPU device")));
    }
    unsafe { (api.commit_device)(device) };
    let oidn = Oidn {
        version: unsafe { (api.get_device_1i)(device, c"version".as_ptr()) },
        api,
        device: Mutex::new(Device {
            handle: device,
            filter: None,
        }),
        path: path.map_or_else(|| PathBuf::from(shown.clone()), Path::to_path_buf),
        _libs: libs,
    };
    oidn.check(oidn.device.lock().unwrap_or_else(|e| e.into_inner()).handle)?;
    if !VERSION_RANGE.contains(&oidn.version) {
        return Err(OidnError::WrongLibrary(format!(
            "{shown} is Open Image Denoise {}",
            oidn.version_string()
        )));
    }
    Ok(oidn)
}

/// Finds and loads the library (see the module comment); the first search's outcome is
/// kept for the whole process.
pub fn load() -> Result<&'static Oidn, OidnError> {
    static LOADED: OnceLock<Result<Oidn, OidnError>> = OnceLock::new();
    LOADED
        .get_or_init(|| {
            let found = candidates()?;
            let named = std::env::var_os("MEDIAREG_OIDN").is_some();
            let mut errors = Vec::new();
            for p in &found {
                match open(Some(p)) {
                    Ok(o) => return Ok(o),
                    Err(e @ OidnError::WrongLibrary(_)) if named => return Err(e),
                    Err(e) => errors.push(e),
                }
            }
            if !named {
                match open(None) {
                    Ok(o) => return Ok(o),
                    Err(e) => errors.push(e),
                }
            }
            // A wrong library says more than "not found".
            let wrong = errors
                .iter()
                .find(|e| matches!(e, OidnError::WrongLibrary(_)));
            Err(wrong
                .or(errors.first())
                .cloned()
                .unwrap_or_else(|| OidnError::NotFound("no library found".to_string())))
        })
        .as_ref()
        .map_err(Clone::clone)
}

impl Oidn {
    /// The library's version as OIDN writes it, e.g. "1.4.3".
    pub fn version_string(&self) -> String {
        let v = self.version;
        format!("{}.{}.{}", v / 10000, v / 100 % 100, v % 100)
    }

    /// Where it was loaded from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn check(&self, device: Handle) -> Result<(), OidnError> {
        let mut msg: *const c_char = std::ptr::null();
        // SAFETY: the device is valid; OIDN owns the message string.
        let code = unsafe { (self.api.get_device_error)(device, &mut msg) };
        if code == 0 {
            return Ok(());
        }
        let text = if msg.is_null() {
            format!("error code {code}")
        } else {
            unsafe { CStr::from_ptr(msg) }
                .to_string_lossy()
                .into_owned()
        };
        Err(OidnError::Failed(text))
    }

    /// OIDN's `RT` filter on a width × height HDR colour image (linear, non-negative,
    /// finite), with the auxiliary images where given. Returns the denoised image, the
    /// same bits for the same input (the input scale is [`autoexposure`]'s).
    pub fn denoise_rt(
        &self,
        width: usize,
        height: usize,
        color: &[[f32; 3]],
        aux: Option<Aux>,
    ) -> Result<Vec<[f32; 3]>, OidnError> {
        let scale = autoexposure(width, height, color);
        self.denoise_rt_scaled(width, height, color, aux, scale)
    }

    /// `denoise_rt` with OIDN's `inputScale`; NaN lets OIDN compute it (its parallel sum:
    /// not reproducible, see the module comment).
    fn denoise_rt_scaled(
        &self,
        width: usize,
        height: usize,
        color: &[[f32; 3]],
        aux: Option<Aux>,
        input_scale: f32,
    ) -> Result<Vec<[f32; 3]>, OidnError> {
        let n = width * height;
        let check = |name: &str, img: &[[f32; 3]], non_negative: bool| {
            if img.len() != n {
                return Err(OidnError::BadInput(format!(
                    "the {name} image has {} pixels, not {width}×{height}",
                    img.len()
                )));
            }
            let bad = img.iter().flatten().filter(|v| !v.is_finite()).count();
            if bad > 0 {
                return Err(OidnError::BadInput(format!(
                    "the {name} image has {bad} NaN or infinite values"
                )));
            }
            if non_negative && img.iter().flatten().any(|&v| v < 0.0) {
                return Err(OidnError::BadInput(format!(
                    "the {name} image has negative values (OIDN's HDR filter takes radiance, \
                     which is non-negative)"
                )));
            }
            Ok(())
        };
        check("colour", color, true)?;
        if let Some(a) = &aux {
            check("albedo", a.albedo, true)?;
            if let Some(nrm) = a.normal {
                check("normal", nrm, false)?;
            }
        }
        if n == 0 {
            return Ok(Vec::new());
        }
        let mut output = vec![[0f32; 3]; n];
        let layout = FilterLayout {
            width,
            height,
            albedo: aux.is_some(),
            normal: aux.is_some_and(|a| a.normal.is_some()),
            clean: aux.is_some_and(|a| a.clean),
        };
        let mut device = self.device.lock().unwrap_or_else(|e| e.into_inner());
        let api = &self.api;
        // SAFETY: every image outlives the filter's execution (the filter keeps their
        // addresses afterwards but is given new ones before it runs again), each is n
        // packed float3 pixels as described, and the device is held locked.
        unsafe {
            let filter = match device.filter {
                Some((kept, filter)) if kept == layout => filter,
                _ => {
                    if let Some((_, old)) = device.filter.take() {
                        (api.release_filter)(old);
                    }
                    let filter = (api.new_filter)(device.handle, c"RT".as_ptr());
                    if filter.is_null() {
                        self.check(device.handle)?;
                        return Err(OidnError::Failed("no RT filter".into()));
                    }
                    device.filter = Some((layout, filter));
                    filter
                }
            };
            let share = |name: &CString, img: *mut c_void| {
                (api.set_shared_filter_image)(
                    filter,
                    name.as_ptr(),
                    img,
                    FORMAT_FLOAT3,
                    width,
                    height,
                    0,
                    0,
                    0,
                );
            };
            let name = |s: &str| CString::new(s).expect("no NUL in a name");
            share(&name("color"), color.as_ptr() as *mut c_void);
            if let Some(a) = &aux {
                share(&name("albedo"), a.albedo.as_ptr() as *mut c_void);
                if let Some(nrm) = a.normal {
                    share(&name("normal"), nrm.as_ptr() as *mut c_void);
                }
                (api.set_filter_1b)(filter, c"cleanAux".as_ptr(), a.clean);
            }
            share(&name("output"), output.as_mut_ptr() as *mut c_void);
            (api.set_filter_1b)(filter, c"hdr".as_ptr(), true);
            (api.set_filter_1f)(filter, c"inputScale".as_ptr(), input_scale);
            (api.commit_filter)(filter);
            let committed = self.check(device.handle);
            if committed.is_ok() {
                (api.execute_filter)(filter);
            }
            let executed = self.check(device.handle);
            if committed.is_err() || executed.is_err() {
                // A filter in an error state is not kept for the next image.
                if let Some((_, f)) = device.filter.take() {
                    (api.release_filter)(f);
                }
            }
            committed.and(executed)?;
        }
        if output.iter().flatten().any(|v| !v.is_finite()) {
            return Err(OidnError::Failed("the output has NaN or Inf".into()));
        }
        Ok(output)
    }
}

/// OIDN 1.4.3's HDR exposure (`getAutoexposure`, core/color.cpp): the image cut into
/// about 16×16-pixel blocks, key 0.18 over 2 to the mean log2 of the blocks' mean
/// luminances above 1e-8; 1 where there is none. Summed in order, in f64, so that it is
/// the same for the same image (OIDN's f32 parallel sum differs in its last bits).
pub fn autoexposure(width: usize, height: usize, color: &[[f32; 3]]) -> f32 {
    const KEY: f64 = 0.18;
    const EPS: f32 = 1e-8;
    const K: usize = 16;
    let (hk, wk) = ((height + K / 2) / K, (width + K / 2) / K);
    let (mut sum, mut count) = (0f64, 0usize);
    for i in 0..hk {
        let (h0, h1) = (i * height / hk, (i + 1) * height / hk);
        for j in 0..wk {
            let (w0, w1) = (j * width / wk, (j + 1) * width / wk);
            let mut l = 0f64;
            for row in color[h0 * width..h1 * width].chunks_exact(width) {
                for c in &row[w0..w1] {
                    // OIDN's luminance weights (color.isph).
                    let y = 0.212671f32 * c[0] + 0.715160f32 * c[1] + 0.072169f32 * c[2];
                    l += y as f64;
                }
            }
            let l = (l / ((h1 - h0) * (w1 - w0)) as f64) as f32;
            if l > EPS {
                sum += (l as f64).log2();
                count += 1;
            }
        }
    }
    if count == 0 {
        return 1.0;
    }
    (KEY / (sum / count as f64).exp2()) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic noisy HDR image: a ramp times uniform noise, some values above 1.
    fn noisy(width: usize, height: usize, seed: u64) -> Vec<[f32; 3]> {
        let mut s = seed;
        let mut uniform = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 40) as f32 / (1u64 << 24) as f32
        };
        (0..width * height)
            .map(|i| {
                let ramp = 2.0 * (i % width) as f32 / width as f32;
                [
                    3.0 * ramp * uniform(),
                    ramp * uniform(),
                    5.0 * uniform() * uniform(),
                ]
            })
            .collect()
    }

    /// The exposure passed to OIDN is its own, to its rounding: the output with it is
    /// the output OIDN's own computation gives (which differs from itself by up to 5e-5).
    /// Power: an exposure 1% off leaves that tolerance on every size.
    #[test]
    fn the_exposure_is_oidns_own() {
        let lib = load().unwrap_or_else(|e| panic!("{e}"));
        let within = |a: &[[f32; 3]], b: &[[f32; 3]]| {
            a.iter()
                .flatten()
                .zip(b.iter().flatten())
                .all(|(a, b)| (a - b).abs() <= 2e-4 * b.abs() + 1e-7)
        };
        for (w, h) in [(160, 120), (37, 29), (300, 17)] {
            let color = noisy(w, h, w as u64);
            let ours = lib.denoise_rt(w, h, &color, None).unwrap();
            let oidns = lib.denoise_rt_scaled(w, h, &color, None, f32::NAN).unwrap();
            assert!(
                within(&ours, &oidns),
                "{w}x{h}: ours differs from OIDN's own"
            );
            let off = 1.01 * autoexposure(w, h, &color);
            let wrong = lib.denoise_rt_scaled(w, h, &color, None, off).unwrap();
            assert!(
                !within(&wrong, &oidns),
                "{w}x{h}: an exposure 1% off passed the tolerance"
            );
        }
        // Darker input, a larger scale: proportional, by its definition.
        let color = noisy(64, 64, 3);
        let dim: Vec<[f32; 3]> = color.iter().map(|p| p.map(|v| v / 8.0)).collect();
        let ratio = autoexposure(64, 64, &dim) / autoexposure(64, 64, &color);
        assert!((ratio - 8.0).abs() < 1e-4, "{ratio}");
        assert_eq!(autoexposure(64, 64, &vec![[0.0; 3]; 64 * 64]), 1.0);
        assert_eq!(
            autoexposure(7, 7, &color[..49]),
            1.0,
            "fewer than half a block"
        );
    }
}
