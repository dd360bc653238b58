//! The `ember-view` binary end to end: bake, headless frame, outputs, reuse of the bake, and
//! the exit status of bad input. Uses a small white furnace (every vertex has the same
//! radiance), so the bake takes well under a second.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// A fresh folder under the system temporary directory.
fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ember-view-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A `gi` scene inside the furnace cube of `data/furnace`, with albedo 0.5 and Ke = 0.1: the
/// radiance everywhere is 0.1 / (1 − 0.5) = 0.2.
fn furnace_scene(dir: &Path, renderer: &str) -> PathBuf {
    let obj = std::fs::read_to_string(workspace().join("data/furnace/mesh/furnace_a050.obj"))
        .expect("data/furnace/mesh/furnace_a050.obj");
    std::fs::write(
        dir.join("furnace_a050.obj"),
        obj.replace("mtllib furnace_a050.mtl", "mtllib grey.mtl"),
    )
    .unwrap();
    std::fs::write(
        dir.join("grey.mtl"),
        "newmtl furnace\nKd 0.5 0.5 0.5\nKs 0 0 0\nKe 0.1 0.1 0.1\nillum 7\n",
    )
    .unwrap();
    let toml = dir.join("furnace_gi.toml");
    std::fs::write(
        &toml,
        format!(
            "[input]\nobjfile = \"furnace_a050.obj\"\n\n\
             [camera]\neye = [0.0, 0.0, 0.0]\nat = [0.0, 0.0, -1.0]\nup = [0.0, 1.0, 0.0]\nfov = 60.0\n\n\
             [film]\nwidth = 40\nheight = 30\n\n[renderer]\n{renderer}\n"
        ),
    )
    .unwrap();
    toml
}

const GI: &str = "realtime = true\ntype = \"gi\"\nmaxDepth = -1\nrrDepth = 5\nrrProb = 0.95\nsamplesByVertex = 64";

fn ember_view(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ember-view"))
        .args(args)
        .output()
        .expect("run ember-view")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn headless_writes_exr_and_png_beside_the_scene_and_reuses_the_bake() {
    let dir = temp_dir("furnace");
    let toml = furnace_scene(&dir, GI);
    let t = toml.to_str().unwrap();
    let o = ember_view(&[t, "--headless", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("adapter "), "prints the adapter: {err}");
    assert!(err.contains("baked "), "{err}");
    assert!(err.contains(" ms"), "prints the frame time: {err}");

    let exr = dir.join("furnace_gi.exr");
    let img = ember_cli::image::read_exr(&exr).expect("EXR next to the TOML");
    assert_eq!((img.width, img.height), (40, 30));
    // Every pixel sees the furnace's walls: about 0.2 everywhere, never above 1.
    let mean = img.mean();
    assert!(
        (mean - glam::Vec3::splat(0.2)).abs().max_element() < 0.03,
        "{mean}"
    );
    assert!(img
        .pixels
        .iter()
        .all(|p| p.min_element() > 0.05 && p.max_element() <= 1.0));
    let png = std::fs::read(dir.join("furnace_gi.png")).expect("PNG beside the EXR");
    assert_eq!(&png[1..4], b"PNG");
    assert!(dir.join("furnace_gi.bake.ply").is_file());

    // The same settings reuse the stored bake; other settings bake again.
    let o = ember_view(&[t, "--headless", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("reusing the bake"), "{}", stderr(&o));
    // An edited material is a different scene: the stored bake is not reused (its file time
    // plays no part; the data the kernel reads is hashed).
    std::fs::write(
        dir.join("grey.mtl"),
        "newmtl furnace\nKd 0.4 0.5 0.5\nKs 0 0 0\nKe 0.1 0.1 0.1\nillum 7\n",
    )
    .unwrap();
    let o = ember_view(&[t, "--headless", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("baked "), "{}", stderr(&o));
    let out = dir.join("other.exr");
    let bake = dir.join("other.ply");
    let o = ember_view(&[
        t,
        "--headless",
        "-q",
        "-o",
        out.to_str().unwrap(),
        "--bake",
        bake.to_str().unwrap(),
        "--samples-per-vertex",
        "4",
        "--width",
        "20",
        "--height",
        "10",
        "--false-colour",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("baked "), "{}", stderr(&o));
    assert!(bake.is_file() && dir.join("other.png").is_file());
    let img = ember_cli::image::read_exr(&out).unwrap();
    assert_eq!((img.width, img.height), (20, 10));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_input_exits_with_status_2() {
    let dir = temp_dir("bad");
    let path_scene = furnace_scene(&dir, "realtime = false\ntype = \"path\"\nspp = 1");
    let p = path_scene.to_str().unwrap();
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec![p.into(), "--headless".into()],
            "not a real-time \"gi\" scene",
        ),
        (
            vec![
                dir.join("missing.toml").to_str().unwrap().into(),
                "--headless".into(),
            ],
            "missing.toml",
        ),
        (
            vec![
                p.into(),
                "--headless".into(),
                "--samples-per-vertex".into(),
                "0".into(),
            ],
            "--samples-per-vertex 0",
        ),
        (
            vec![p.into(), "--headless".into(), "--width".into(), "0".into()],
            "--width 0",
        ),
        (
            vec![
                p.into(),
                "--headless".into(),
                "-o".into(),
                dir.join("no/such/dir/x.exr").to_str().unwrap().into(),
            ],
            "does not exist",
        ),
    ];
    for (args, message) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = ember_view(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        let err = stderr(&o);
        assert!(
            err.contains("error: ") && err.contains(message),
            "{args:?}: {err}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
