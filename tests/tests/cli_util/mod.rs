//! Helpers for tests that run the `ember` binary: locating (and building) it, fresh temporary
//! directories, and a small valid scene to start from.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::OnceLock;

/// The `ember` binary of the profile this test was built with: the test binary lives in
/// `<target>/<profile>/deps/`, the binary in `<target>/<profile>/`.
///
/// Cargo builds binaries of other packages only for their own integration tests, so it is built
/// here, once per test process, with `cargo build -p ember-cli --bin ember` (plus `--release`
/// in an optimised test build) into the same target directory. The build also runs when the
/// binary exists, because a binary left over from before a change in host-cli would otherwise
/// be tested silently; when it is up to date, the build is a no-op.
pub fn ember() -> &'static Path {
    static BIN: OnceLock<PathBuf> = OnceLock::new();
    BIN.get_or_init(|| build_binary("ember-cli", "ember"))
}

/// The `ember-view` binary, built like [`ember`] and placed beside it (where `ember render`
/// looks for it).
pub fn ember_view() -> &'static Path {
    static BIN: OnceLock<PathBuf> = OnceLock::new();
    BIN.get_or_init(|| build_binary("ember-viewer", "ember-view"))
}

fn build_binary(package: &str, name: &str) -> PathBuf {
    {
        let exe = std::env::current_exe().expect("current_exe");
        let deps = exe.parent().expect("test binary has a directory");
        let profile_dir = deps.parent().expect("deps directory has a parent");
        let target_dir = profile_dir
            .parent()
            .expect("profile directory has a parent");
        let bin = profile_dir.join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
        let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
        let mut cmd = Command::new(cargo);
        cmd.args(["build", "--quiet", "-p", package, "--bin", name])
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .env("CARGO_TARGET_DIR", target_dir);
        if !cfg!(debug_assertions) {
            cmd.arg("--release");
        }
        match cmd.status() {
            Ok(s) if s.success() => {}
            // Without a working cargo (test binary run by hand), an existing binary will do.
            Ok(s) if !bin.exists() => panic!("`cargo build -p {package} --bin {name}` failed: {s}"),
            Err(e) if !bin.exists() => panic!("cannot run cargo to build {name}: {e}"),
            _ => eprintln!(
                "warning: could not rebuild {}; using it as is",
                bin.display()
            ),
        }
        assert!(
            bin.is_file(),
            "{name} binary not found at {} after building it",
            bin.display()
        );
        bin
    }
}

/// Runs `ember` with the given arguments.
pub fn run_ember<I, S>(args: I) -> Output
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    Command::new(ember())
        .args(args)
        .output()
        .expect("cannot run the ember binary")
}

/// A fresh directory under the system temporary directory. It is removed when dropped, unless
/// the test is failing (then it is kept for inspection and its path is printed).
#[derive(Debug)]
pub struct TempDir {
    path: PathBuf,
}

impl TempDir {
    pub fn new(name: &str) -> Self {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        let slug: String = name
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
            .collect();
        let path = std::env::temp_dir().join(format!(
            "ember-test-{slug}-{}-{n}-{nanos}",
            std::process::id()
        ));
        if path.exists() {
            std::fs::remove_dir_all(&path).expect("cannot clear old temporary directory");
        }
        std::fs::create_dir_all(&path).expect("cannot create temporary directory");
        Self { path }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Writes `contents` to `name` inside the directory and returns the file's path.
    pub fn write(&self, name: &str, contents: &str) -> PathBuf {
        let p = self.path.join(name);
        std::fs::write(&p, contents).expect("cannot write test input");
        p
    }

    /// All regular files below the directory, recursively.
    pub fn files(&self) -> Vec<PathBuf> {
        fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
            for e in std::fs::read_dir(dir).expect("read_dir").flatten() {
                let p = e.path();
                if p.is_dir() {
                    walk(&p, out);
                } else {
                    out.push(p);
                }
            }
        }
        let mut out = Vec::new();
        walk(&self.path, &mut out);
        out.sort();
        out
    }

    /// Files that ember's output code may have written: images and atomic-write temporaries.
    pub fn outputs(&self) -> Vec<PathBuf> {
        self.files()
            .into_iter()
            .filter(|p| {
                let name = p
                    .file_name()
                    .map_or_else(String::new, |n| n.to_string_lossy().to_ascii_lowercase());
                name.ends_with(".exr") || name.ends_with(".png") || name.ends_with(".tmp")
            })
            .collect()
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!("test inputs kept in {}", self.path.display());
        } else {
            let _ = std::fs::remove_dir_all(&self.path);
        }
    }
}

/// A valid TinyRender scene: an 8x8 path-traced view of `quad.obj`.
pub const SCENE_TOML: &str = r#"[input]
objfile = "quad.obj"

[camera]
eye = [0.0, 0.0, 3.0]
at = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov = 40.0

[film]
width = 8
height = 8

[renderer]
realtime = false
type = "path"
isExplicit = true
maxDepth = -1
rrDepth = 5
rrProb = 0.95
spp = 2
"#;

/// A unit-radiance emissive quad in the z = 0 plane, facing +z (towards the camera of
/// [`SCENE_TOML`]), counter-clockwise, with vertex normals.
pub const QUAD_OBJ: &str = "mtllib quad.mtl
o light
v -1 -1 0
v 1 -1 0
v 1 1 0
v -1 1 0
vn 0 0 1
usemtl light
f 1//1 2//1 3//1 4//1
";

pub const QUAD_MTL: &str = "newmtl light
Kd 0 0 0
Ke 1 1 1
illum 7
";

/// `text` with the first occurrence of `from` replaced by `to`; panics when `from` is absent,
/// so that a test cannot silently run on the unmodified input.
pub fn edit(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "{from:?} not found in test input");
    text.replacen(from, to, 1)
}
