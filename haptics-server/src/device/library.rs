//! Vendor libraries loaded at run time (OpenHaptics `libHD.so`, Force Dimension `libdhd.so`):
//! when one does not load, say which file names were looked for and where, and whether a
//! file the loader cannot see was found anyway (a versioned `libdhd.so.3` without its
//! unversioned link, a copy under `/opt`), so the error tells a lab what to do.

use std::path::{Path, PathBuf};

use serde::Serialize;

/// Directories searched besides the loader's: where vendor installers and SDK unpackings put
/// their libraries.
pub const VENDOR_DIRS: [&str; 4] = [
    "/opt/forcedimension/lib",
    "/opt/OpenHaptics/lib",
    "/usr/local/forcedimension/lib",
    "/opt/3DSystems/lib",
];

/// Where a library name was looked for, and what was found.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Search {
    /// The configured name or path.
    pub requested: String,
    /// File names matched, e.g. `libdhd.so` and `libdhd.so.*`.
    pub names: Vec<String>,
    /// Directories looked in (in the loader's order, then vendor directories).
    pub dirs: Vec<PathBuf>,
    /// Matching files found there.
    pub found: Vec<PathBuf>,
}

/// The directories the dynamic loader searches (LD_LIBRARY_PATH, /etc/ld.so.conf and its
/// includes, the system defaults), then [`VENDOR_DIRS`]; duplicates and missing ones dropped.
pub fn search_dirs() -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> = Vec::new();
    if let Some(p) = std::env::var_os("LD_LIBRARY_PATH") {
        dirs.extend(std::env::split_paths(&p).filter(|d| !d.as_os_str().is_empty()));
    }
    dirs.extend(ld_so_conf(Path::new("/etc/ld.so.conf"), 0));
    let arch = format!("{}-linux-gnu", std::env::consts::ARCH);
    for d in [
        format!("/lib/{arch}"),
        format!("/usr/lib/{arch}"),
        "/lib64".into(),
        "/usr/lib64".into(),
        "/lib".into(),
        "/usr/lib".into(),
        "/usr/local/lib".into(),
    ] {
        dirs.push(PathBuf::from(d));
    }
    dirs.extend(VENDOR_DIRS.iter().map(PathBuf::from));
    let mut out: Vec<PathBuf> = Vec::new();
    for d in dirs {
        if d.is_dir() && !out.contains(&d) {
            out.push(d);
        }
    }
    out
}

/// Directories listed by an ld.so.conf file, following `include` lines (one `*` pattern in
/// the file name, as Debian's `include /etc/ld.so.conf.d/*.conf`).
fn ld_so_conf(path: &Path, depth: usize) -> Vec<PathBuf> {
    let Ok(text) = std::fs::read_to_string(path) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for line in text.lines() {
        let line = line.split('#').next().unwrap_or("").trim();
        if let Some(pattern) = line.strip_prefix("include") {
            if depth > 3 {
                continue;
            }
            let pattern = Path::new(pattern.trim());
            let (Some(dir), Some(file)) = (pattern.parent(), pattern.file_name()) else {
                continue;
            };
            let file = file.to_string_lossy();
            let (prefix, suffix) = file.split_once('*').unwrap_or((&file, ""));
            let mut confs: Vec<PathBuf> = std::fs::read_dir(dir)
                .into_iter()
                .flatten()
                .flatten()
                .map(|e| e.path())
                .filter(|p| {
                    p.file_name()
                        .map(|n| n.to_string_lossy())
                        .is_some_and(|n| n.starts_with(prefix) && n.ends_with(suffix))
                })
                .collect();
            confs.sort();
            for c in confs {
                out.extend(ld_so_conf(&c, depth + 1));
            }
        } else if line.starts_with('/') {
            out.push(PathBuf::from(line));
        }
    }
    out
}

/// Look for `requested` (a bare file name such as `libdhd.so`) and its versioned files
/// (`libdhd.so.*`) in [`search_dirs`]. A path (with a `/`) is looked at alone.
pub fn search(requested: &str) -> Search {
    if requested.contains('/') {
        let p = PathBuf::from(requested);
        return Search {
            requested: requested.into(),
            names: vec![requested.into()],
            dirs: Vec::new(),
            found: if p.exists() { vec![p] } else { Vec::new() },
        };
    }
    let dirs = search_dirs();
    let mut found = Vec::new();
    for d in &dirs {
        let mut here: Vec<PathBuf> = std::fs::read_dir(d)
            .into_iter()
            .flatten()
            .flatten()
            .filter(|e| {
                let n = e.file_name();
                let n = n.to_string_lossy();
                n == requested
                    || n.strip_prefix(requested)
                        .is_some_and(|rest| rest.starts_with('.'))
            })
            .map(|e| e.path())
            .collect();
        here.sort();
        found.extend(here);
    }
    Search {
        requested: requested.into(),
        names: vec![requested.into(), format!("{requested}.*")],
        dirs,
        found,
    }
}

impl Search {
    /// Why `requested` did not load, for a library whose setting is `key` (e.g.
    /// `device.dhd.library`) and flag `flag` (e.g. `--dhd-library`); `install` says where the
    /// vendor's files come from. `load_error` is the loader's own message.
    pub fn explain(&self, load_error: &str, key: &str, flag: &str, install: &str) -> String {
        if self.dirs.is_empty() {
            // A path was given.
            return if self.found.is_empty() {
                format!(
                    "{:?} does not exist; {install}, and set {key} ({flag}) to the library's path",
                    self.requested
                )
            } else {
                format!(
                    "{:?} exists but does not load ({load_error}): the wrong architecture, or \
                     a library it needs is missing (`ldd {}` lists them)",
                    self.requested, self.requested
                )
            };
        }
        let dirs: Vec<String> = self.dirs.iter().map(|d| d.display().to_string()).collect();
        let looked = format!(
            "looked for {} in {} (LD_LIBRARY_PATH, /etc/ld.so.conf, the system and vendor \
             directories)",
            self.names.join(" and "),
            dirs.join(", ")
        );
        if let Some(f) = self.found.first() {
            let others = if self.found.len() > 1 {
                format!(" (and {} more)", self.found.len() - 1)
            } else {
                String::new()
            };
            return format!(
                "the loader cannot load {:?} ({load_error}), but {} is there{others}: set {key} \
                 ({flag}) to that path, or make it loadable by name (a {} link beside it, that \
                 directory in /etc/ld.so.conf.d, then `sudo ldconfig`); {looked}",
                self.requested,
                f.display(),
                self.requested
            );
        }
        let mut install = install.to_owned();
        if let Some(first) = install.get(..1) {
            install.replace_range(..1, &first.to_uppercase());
        }
        format!(
            "{:?} is not installed: the loader found nothing ({load_error}); {looked}, and found \
             none. {install}, or set {key} ({flag}) to the library's path",
            self.requested
        )
    }
}

/// The file a loaded library came from, found through one of its symbols (`dladdr`).
pub fn loaded_path(lib: &libloading::Library, symbol: &str) -> Option<PathBuf> {
    // SAFETY: only the symbol's address is taken; it is not called or dereferenced.
    let sym = unsafe { lib.get::<*mut std::ffi::c_void>(symbol.as_bytes()) }.ok()?;
    let addr: *mut std::ffi::c_void = *sym;
    let mut info = std::mem::MaybeUninit::<libc::Dl_info>::zeroed();
    // SAFETY: `addr` lies in a loaded library; `info` is valid for writes.
    let ok = unsafe { libc::dladdr(addr as *const _, info.as_mut_ptr()) };
    if ok == 0 {
        return None;
    }
    // SAFETY: dladdr succeeded, so `info` is initialised.
    let info = unsafe { info.assume_init() };
    if info.dli_fname.is_null() {
        return None;
    }
    // SAFETY: dli_fname is a NUL-terminated string owned by the loader while the library is
    // loaded (it is, through `lib`).
    let name = unsafe { std::ffi::CStr::from_ptr(info.dli_fname) };
    Some(PathBuf::from(name.to_string_lossy().into_owned()))
}

/// A vendor library named in a device config, loaded at run time.
#[derive(Debug, Clone, Copy)]
pub struct Vendor<'a> {
    /// What it is, e.g. "the OpenHaptics HD library".
    pub what: &'a str,
    /// The config key that names it, e.g. `device.openhaptics.library`.
    pub config_key: &'a str,
    /// The command-line flag that names it.
    pub flag: &'a str,
    /// How to install it.
    pub install_hint: &'a str,
    /// Said after the missing functions (e.g. a likely SDK version), or "".
    pub missing_hint: &'a str,
}

/// Load `library` and check that it has every `required` symbol. Errors name the file names
/// looked for and where ([`search`]), or the missing functions.
pub fn open(
    library: &str,
    required: &[&str],
    vendor: &Vendor<'_>,
) -> Result<libloading::Library, super::DeviceError> {
    // SAFETY: loading runs the library's initialisers; the vendor libraries (and the tests'
    // stand-ins) are C/C++ libraries whose initialisers have no preconditions on us.
    let lib = unsafe { libloading::Library::new(library) }.map_err(|e| {
        let why = search(library).explain(
            &e.to_string(),
            vendor.config_key,
            vendor.flag,
            vendor.install_hint,
        );
        super::DeviceError::Missing(format!("cannot load {} {library:?}: {why}", vendor.what))
    })?;
    let missing: Vec<&str> = required
        .iter()
        // SAFETY: only the symbol's presence is checked; the pointer is not used.
        .filter(|name| unsafe { lib.get::<*const std::ffi::c_void>(name.as_bytes()) }.is_err())
        .copied()
        .collect();
    if !missing.is_empty() {
        return Err(super::DeviceError::Missing(format!(
            "{library:?} loads but lacks {}{}",
            missing.join(", "),
            vendor.missing_hint
        )));
    }
    Ok(lib)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_library_names_what_was_searched_and_where() {
        let s = search("libnot-a-real-haptics-library.so");
        assert!(s.found.is_empty());
        assert!(!s.dirs.is_empty(), "some system library directory exists");
        let e = s.explain("not found", "device.x.library", "--x-library", "install X");
        assert!(
            e.contains("libnot-a-real-haptics-library.so and libnot-a-real-haptics-library.so.*")
                && e.contains("Install X")
                && e.contains("device.x.library (--x-library)"),
            "{e}"
        );
    }

    #[test]
    fn a_versioned_file_beside_a_missing_name_is_pointed_at() {
        let dir = tempfile::tempdir().unwrap();
        let versioned = dir.path().join("libfd-test.so.3.17.0");
        std::fs::write(&versioned, b"").unwrap();
        let s = Search {
            requested: "libfd-test.so".into(),
            names: vec!["libfd-test.so".into(), "libfd-test.so.*".into()],
            dirs: vec![dir.path().into()],
            found: vec![versioned.clone()],
        };
        let e = s.explain(
            "not found",
            "device.dhd.library",
            "--dhd-library",
            "install",
        );
        assert!(e.contains(&versioned.display().to_string()), "{e}");
        let p = search(versioned.to_str().unwrap());
        assert_eq!(p.found, std::slice::from_ref(&versioned));
        let e = p.explain("invalid ELF header", "k", "f", "i");
        assert!(
            e.contains("exists but does not load") && e.contains("ldd"),
            "{e}"
        );
    }
}
