//! `ember render` on a real-time `gi` scene hands it to `ember-view --headless` beside it: one
//! command renders every TinyRender scene type.

mod cli_util;
mod common;

use cli_util::{ember_view, run_ember, TempDir};
use common::*;

#[test]
fn ember_render_draws_gi_scenes_through_the_viewer() {
    ember_view();
    // ember-view caches the bake beside the scene unless that folder is read-only; a cache
    // this test creates in the shared data is removed again.
    let beside = cbox_scene("cbox_gi_low_realtime.bake.ply");
    let existed = beside.exists();
    let dir = TempDir::new("gi-cli");
    let out = dir.path().join("gi.exr");
    let run = run_ember([
        "render",
        cbox_scene("cbox_gi_low_realtime.toml").to_str().unwrap(),
        "-q",
        "--spp",
        "8",
        "--width",
        "200",
        "--height",
        "150",
        "-o",
        out.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    let img = ember_cli::image::read_exr(&out).unwrap();
    assert_eq!((img.width, img.height), (200, 150));
    assert!(out.with_extension("png").is_file());
    // Real-time output is clamped to [0, 1]; the reference's mean is 0.11 (red).
    assert!(img
        .pixels
        .iter()
        .all(|p| p.min_element() >= 0.0 && p.max_element() <= 1.0));
    let m = img.mean();
    assert!(m.x > 0.08 && m.x < 0.2, "mean {m}");
    if !existed && beside.exists() {
        let _ = std::fs::remove_file(&beside);
    }
}

/// A copy of `data/cornell-box` (so the bake cache lands in a temporary folder).
fn cornell_copy(dir: &TempDir) -> std::path::PathBuf {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/cornell-box");
    std::fs::create_dir_all(dir.path().join("mesh")).unwrap();
    let toml = "cornell_box_gi.toml";
    std::fs::copy(data.join(toml), dir.path().join(toml)).unwrap();
    for e in std::fs::read_dir(data.join("mesh")).unwrap().flatten() {
        std::fs::copy(e.path(), dir.path().join("mesh").join(e.file_name())).unwrap();
    }
    dir.path().join("cornell_box_gi.toml")
}

#[test]
fn ember_render_refuses_path_tracing_options_on_gi_scenes_and_forwards_the_rest() {
    ember_view();
    let dir = TempDir::new("gi-cli-options");
    let toml = cornell_copy(&dir);
    let t = toml.to_str().unwrap();
    for (flag, value) in [
        ("--shard", Some("0/2")),
        ("--integrator", Some("mis")),
        ("--tile", Some("8")),
        ("--max-memory-gib", Some("4")),
        ("--sampler", Some("zsobol")),
    ] {
        let mut args = vec!["render", t, "-q", "--width", "32", "--height", "24", flag];
        args.extend(value);
        let run = run_ember(&args);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{flag}: {stderr}");
        let lines: Vec<&str> = stderr.lines().collect();
        assert_eq!(lines.len(), 1, "{flag}: one line: {stderr}");
        assert!(
            lines[0].starts_with("error: ")
                && lines[0].contains(&format!(
                    "{flag} does not apply to a real-time \"gi\" scene"
                )),
            "{flag}: {stderr}"
        );
        assert!(
            !dir.path().join("cornell_box_gi.exr").exists(),
            "{flag}: nothing written"
        );
    }
    // Every option that applies reaches ember-view: seed, threads, size, samples per vertex,
    // --no-shortcuts (bit-identical bake), output.
    let out = |name: &str| dir.path().join(name);
    let render = |name: &str, seed: &str, extra: &[&str]| {
        let o = out(name);
        let mut args = vec![
            "render",
            t,
            "-q",
            "--width",
            "32",
            "--height",
            "24",
            "--spp",
            "4",
            "--seed",
            seed,
            "--threads",
            "1",
            "-o",
        ];
        args.push(o.to_str().unwrap());
        args.extend_from_slice(extra);
        let run = run_ember(&args);
        assert!(
            run.status.success(),
            "{extra:?}: {}",
            String::from_utf8_lossy(&run.stderr)
        );
        ember_cli::image::read_exr(&o).unwrap()
    };
    let a = render("a.exr", "7", &[]);
    assert_eq!((a.width, a.height), (32, 24));
    // The cached bake would hide --no-shortcuts and --seed: remove it between runs.
    let bake = dir.path().join("cornell_box_gi.bake.ply");
    let _ = std::fs::remove_file(&bake);
    let b = render("b.exr", "7", &["--no-shortcuts"]);
    assert_eq!(a, b, "--no-shortcuts gives the same frame");
    let _ = std::fs::remove_file(&bake);
    let c = render("c.exr", "8", &[]);
    assert_ne!(a, c, "--seed reaches the bake");
}
