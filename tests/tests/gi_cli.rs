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
