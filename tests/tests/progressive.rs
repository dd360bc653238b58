//! host-cli's `Progressive` renderer (what `ember render` and the path-traced view of
//! `ember-view` both drive) against `render()`: any sequence of passes that reaches N spp gives
//! `ember render`'s image at N spp bit for bit, including after a restart, after an abandoned
//! pass, and at spp that are not a multiple of the pass size.

use ember_cli::render::{pass_size, render, Progressive, RenderSettings, Rendered, Shard};
use ember_cli::LoadedScene;
use ember_kernel::integrator::Integrator;
use ember_kernel::scene::SceneView;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

const W: u32 = 40;
const H: u32 = 30;

fn cornell() -> LoadedScene {
    let toml = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/cornell-box/cornell_box.toml");
    LoadedScene::load(&toml).expect("data/cornell-box/cornell_box.toml")
}

fn settings(scene: &LoadedScene, integrator: Integrator, spp: u32, tile: u32) -> RenderSettings {
    let (_, path, _) = scene.path_settings().unwrap();
    RenderSettings {
        integrator,
        path,
        spp,
        seed: 0x5eed,
        sampler: ember_kernel::sampler::SamplerKind::Independent,
        tile,
        threads: 2,
        progress: false,
        shard: Shard::WHOLE,
        strategies: None,
    }
}

fn bits(r: &Rendered) -> (Vec<[u32; 3]>, Vec<[u32; 3]>) {
    let b = |img: &ember_cli::image::Image| {
        img.pixels
            .iter()
            .map(|p| p.to_array().map(f32::to_bits))
            .collect::<Vec<_>>()
    };
    (b(&r.image), b(&r.variance))
}

fn assert_same(got: &Rendered, want: &Rendered, what: &str) {
    assert_eq!(got.spp, want.spp, "{what}: spp");
    let (gi, gv) = bits(got);
    let (wi, wv) = bits(want);
    let differing = gi.iter().zip(&wi).filter(|(a, b)| a != b).count();
    assert_eq!(
        differing, 0,
        "{what}: {differing} pixels differ from render()"
    );
    assert_eq!(gv, wv, "{what}: variances differ");
    assert_eq!(got.invalid_samples, want.invalid_samples, "{what}");
    assert_eq!(got.rays, want.rays, "{what}: rays");
}

fn drive(p: &mut Progressive, view: &SceneView<'_>, passes: &[u32]) {
    for &n in passes {
        assert!(p.render_pass(view, n, &|| false, &|_| {}));
    }
}

#[test]
fn passes_of_any_size_give_render_bit_for_bit() {
    let scene = cornell();
    let view = scene.data.view();
    let camera = scene.camera(W, H);
    for integrator in [
        Integrator::PathImplicit,
        Integrator::PathExplicit,
        Integrator::PathMis,
    ] {
        // 37 spp: render() makes passes of 8 (four of them and one of 5; the splatting
        // integrators' would be of 3).
        let s = settings(&scene, integrator, 37, 16);
        assert_eq!(pass_size(37, integrator.splats()), 8);
        assert_eq!(pass_size(37, true), 3);
        let want = render(&view, &camera, &s);
        // Passes that have nothing to do with render()'s, in another tile size.
        let mut p = Progressive::new(camera, &settings(&scene, integrator, 37, 7));
        drive(&mut p, &view, &[1, 5, 2, 13, 16]);
        assert_eq!(p.spp(), 37);
        assert_same(
            &p.snapshot(),
            &want,
            &format!("{integrator:?}, passes 1+5+2+13+16"),
        );
        // One sample at a time, as the view's first passes are.
        let mut p = Progressive::new(camera, &s);
        drive(&mut p, &view, &[1; 37]);
        assert_same(
            &p.snapshot(),
            &want,
            &format!("{integrator:?}, 37 passes of 1"),
        );
    }
}

#[test]
fn a_restart_and_an_abandoned_pass_change_nothing() {
    let scene = cornell();
    let view = scene.data.view();
    let camera = scene.camera(W, H);
    let s = settings(&scene, Integrator::PathMis, 11, 8);
    let want = render(&view, &camera, &s);
    let mut p = Progressive::new(camera, &s);
    drive(&mut p, &view, &[3]);
    // A pass stopped after a few tiles leaves the sums as they were.
    let tiles_started = AtomicUsize::new(0);
    let stopped = !p.render_pass(
        &view,
        4,
        &|| tiles_started.fetch_add(1, Ordering::Relaxed) >= 3,
        &|_| {},
    );
    assert!(stopped, "the pass must report that it was abandoned");
    assert_eq!(p.spp(), 3);
    drive(&mut p, &view, &[8]);
    assert_same(&p.snapshot(), &want, "after an abandoned pass");

    // Another camera and integrator, then back: the accumulation starts from zero each time.
    let mut moved = scene.file.camera.clone();
    moved.eye[0] += 0.1;
    let other_camera = ember_kernel::camera::Camera::look_at(
        moved.eye.into(),
        moved.at.into(),
        moved.up.into(),
        moved.fov,
        W,
        H,
    );
    let other = settings(&scene, Integrator::PathImplicit, 5, 8);
    p.restart(other_camera, &other);
    assert_eq!(p.spp(), 0);
    drive(&mut p, &view, &[2, 3]);
    assert_same(
        &p.snapshot(),
        &render(&view, &other_camera, &other),
        "restarted with another camera and integrator",
    );
    p.restart(camera, &s);
    drive(&mut p, &view, &[10, 1]);
    assert_same(&p.snapshot(), &want, "restarted with the first camera");
}

#[test]
fn the_preview_is_the_first_sample_of_one_pixel_per_block() {
    let scene = cornell();
    let view = scene.data.view();
    // An odd size: the last blocks are partial.
    let camera = scene.camera(W + 1, H + 1);
    let s = settings(&scene, Integrator::PathExplicit, 1, 16);
    let one = render(&view, &camera, &s);
    let p = Progressive::new(camera, &s);
    let preview = p.preview(&view, 2, &|| false).expect("not stopped");
    let w = W + 1;
    for y in 0..H + 1 {
        for x in 0..w {
            let corner = one.image.at(x & !1, y & !1);
            assert_eq!(
                preview.at(x, y).to_array().map(f32::to_bits),
                corner.to_array().map(f32::to_bits),
                "preview pixel ({x}, {y})"
            );
        }
    }
    assert!(p.preview(&view, 2, &|| true).is_none(), "a stopped preview");
    assert_eq!(p.spp(), 0, "a preview does not accumulate");
}
