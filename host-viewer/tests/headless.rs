//! Headless rendering on the machine's adapter (lavapipe on machines without a GPU: Debian
//! `mesa-vulkan-drivers`). A missing adapter FAILS these tests: they never skip.
//!
//! The scenes are hand-made meshes in the plane z = 0 (unless said otherwise) seen by a camera
//! at (0, 0, 3) looking at the origin with a 60° vertical field of view, on small films.

use ember_cli::bake::BakedMesh;
use ember_cli::scene_file::CameraDesc;
use ember_viewer::{
    linear_to_srgb8, render_headless, srgb8_to_linear_table, Frame, HeadlessGpu, ViewCamera,
    ViewerError,
};
use glam::{Vec2, Vec3};
use std::sync::OnceLock;

const W: u32 = 64;
const H: u32 = 48;

fn camera() -> CameraDesc {
    CameraDesc {
        eye: [0.0, 0.0, 3.0],
        at: [0.0, 0.0, 0.0],
        up: [0.0, 1.0, 0.0],
        fov: 60.0,
    }
}

/// One device for all tests (creating one per test is slow on a software driver).
fn gpu() -> &'static HeadlessGpu {
    static GPU: OnceLock<Result<HeadlessGpu, String>> = OnceLock::new();
    match GPU.get_or_init(|| HeadlessGpu::new().map_err(|e| e.to_string())) {
        Ok(g) => g,
        Err(e) => panic!("no GPU adapter, so the viewer cannot be tested: {e}"),
    }
}

fn render(mesh: &BakedMesh, w: u32, h: u32, false_colour: bool) -> Frame {
    gpu()
        .render(mesh, &camera(), w, h, false_colour)
        .unwrap_or_else(|e| panic!("headless render failed: {e}"))
}

/// Pixel coordinates (continuous, origin at the top-left corner) of a world point.
fn project(p: Vec3, w: u32, h: u32) -> Vec2 {
    let ndc = ViewCamera::from_desc(&camera())
        .view_proj(w as f32 / h as f32)
        .project_point3(p);
    Vec2::new(
        (ndc.x + 1.0) * 0.5 * w as f32,
        (1.0 - ndc.y) * 0.5 * h as f32,
    )
}

/// The pixel containing the projection of a world point.
fn pixel_of(p: Vec3, w: u32, h: u32) -> (u32, u32) {
    let q = project(p, w, h);
    (q.x as u32, q.y as u32)
}

fn srgb8(f: &Frame, x: u32, y: u32) -> [u8; 3] {
    let i = 3 * (y * f.image.width + x) as usize;
    [f.srgb8[i], f.srgb8[i + 1], f.srgb8[i + 2]]
}

fn push_vertex(m: &mut BakedMesh, p: [f32; 3], c: [f32; 3]) -> u32 {
    m.positions.push(p);
    m.normals.push([0.0, 0.0, 1.0]);
    m.colors.push(c);
    (m.positions.len() - 1) as u32
}

/// An axis-aligned rectangle [x0, x1] × [y0, y1] at depth z, one colour, as two triangles.
fn quad(m: &mut BakedMesh, x0: f32, y0: f32, x1: f32, y1: f32, z: f32, c: [f32; 3]) {
    let a = push_vertex(m, [x0, y0, z], c);
    let b = push_vertex(m, [x1, y0, z], c);
    let d = push_vertex(m, [x1, y1, z], c);
    let e = push_vertex(m, [x0, y1, z], c);
    m.triangles.push([a, b, d]);
    m.triangles.push([a, d, e]);
}

/// Asserts that an 8-bit code is the correctly rounded sRGB encoding of `linear`, give or take
/// one code (GPUs may round the sRGB encoding either way).
fn assert_code(got: u8, linear: f32, what: &str) {
    let want = linear_to_srgb8(linear);
    assert!(
        got.abs_diff(want) <= 1,
        "{what}: sRGB code {got}, expected {want} (linear {linear})"
    );
}

#[test]
fn adapter_is_found() {
    // Fails, naming what to install, when there is no adapter.
    let info = gpu().info();
    eprintln!(
        "adapter: {} ({:?}, {:?})",
        info.name, info.backend, info.device_type
    );
    assert!(matches!(
        info.backend,
        wgpu::Backend::Vulkan | wgpu::Backend::Gl
    ));
}

#[test]
fn no_adapter_error_names_what_to_install() {
    let e = ViewerError::NoAdapter(format!("no adapter; {}", ember_viewer::gpu::INSTALL_HINT));
    assert!(e
        .to_string()
        .contains("apt-get install mesa-vulkan-drivers"));
    assert_eq!(e.exit_code(), 1);
}

#[test]
fn constant_colours_clamp_and_row_zero_is_top() {
    let mut m = BakedMesh::default();
    // Both rectangles lie in the upper half of the view (y > 0); the view's half-height at
    // z = 0 is 3 tan 30° = 1.73, its half-width 2.31.
    quad(&mut m, -1.6, 0.3, -0.2, 1.5, 0.0, [0.25; 3]);
    quad(&mut m, 0.2, 0.3, 1.6, 1.5, 0.0, [2.0, 0.25, 0.0]);
    // Through the convenience entry point (its own device).
    let f = render_headless(&m, &camera(), W, H, false).expect("headless render");
    assert_eq!((f.image.width, f.image.height), (W, H));
    assert_eq!(f.image.pixels.len(), (W * H) as usize);
    assert_eq!(f.srgb8.len(), 3 * (W * H) as usize);

    // Inside: 0.25 within 8-bit sRGB quantisation; 2.0 clamped to exactly 1; 0 stays 0.
    let (x, y) = pixel_of(Vec3::new(-0.9, 0.9, 0.0), W, H);
    let c = srgb8(&f, x, y);
    for ch in c {
        assert_code(ch, 0.25, "grey 0.25");
    }
    let v = f.image.at(x, y);
    assert!((v - Vec3::splat(0.25)).abs().max_element() < 0.005, "{v}");
    let (x, y) = pixel_of(Vec3::new(0.9, 0.9, 0.0), W, H);
    let c = srgb8(&f, x, y);
    assert_eq!((c[0], c[2]), (255, 0), "channel order / clamping: {c:?}");
    assert_code(c[1], 0.25, "green 0.25");
    let v = f.image.at(x, y);
    assert_eq!((v.x, v.z), (1.0, 0.0));

    // Outside: exactly 0. The lower half (rows H/2..H) is empty, as are the gap between the
    // rectangles and the top rows.
    for y in H / 2..H {
        for x in 0..W {
            assert_eq!(
                f.image.at(x, y),
                Vec3::ZERO,
                "pixel ({x}, {y}) of the lower half"
            );
        }
    }
    let (x, y) = pixel_of(Vec3::new(0.0, 0.9, 0.0), W, H);
    assert_eq!(f.image.at(x, y), Vec3::ZERO);
    assert_eq!(f.image.at(0, 0), Vec3::ZERO);

    // The lit pixels of the left rectangle are exactly those whose centres its projection
    // covers (give or take the pixels its edges pass through): fov, aspect and orientation.
    let lo = project(Vec3::new(-1.6, 1.5, 0.0), W, H);
    let hi = project(Vec3::new(-0.2, 0.3, 0.0), W, H);
    for y in 0..H {
        for x in 0..W / 2 {
            let centre = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            let inside = centre.cmpgt(lo + 0.01).all() && centre.cmplt(hi - 0.01).all();
            let outside = centre.cmplt(lo - 0.01).any() || centre.cmpgt(hi + 0.01).any();
            let lit = f.image.at(x, y) != Vec3::ZERO;
            if inside {
                assert!(lit, "pixel ({x}, {y}) should be lit");
            }
            if outside {
                assert!(!lit, "pixel ({x}, {y}) should be dark");
            }
        }
    }
}

#[test]
fn gouraud_interpolates_linear_colour() {
    let mut m = BakedMesh::default();
    let p = [[-1.5, -1.2, 0.0], [1.5, -1.2, 0.0], [0.0, 1.4, 0.0]];
    let c = [0.0f32, 0.5, 1.0];
    for (p, c) in p.iter().zip(c) {
        push_vertex(&mut m, *p, [c; 3]);
    }
    m.triangles.push([0, 1, 2]);
    let f = render(&m, W, H, false);

    // Expected value at each pixel centre: the barycentric mix of the vertex colours, in
    // screen space (exact here, the triangle being parallel to the image plane).
    let s: Vec<Vec2> = p.iter().map(|&q| project(Vec3::from(q), W, H)).collect();
    let area = (s[1] - s[0]).perp_dot(s[2] - s[0]);
    let mut checked = 0;
    let mut codes = std::collections::BTreeSet::new();
    for y in 0..H {
        for x in 0..W {
            let q = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            let b = [
                (s[2] - s[1]).perp_dot(q - s[1]) / area,
                (s[0] - s[2]).perp_dot(q - s[2]) / area,
                (s[1] - s[0]).perp_dot(q - s[0]) / area,
            ];
            if b.iter().any(|&b| b < 0.02) {
                continue;
            }
            let expected = b[0] * c[0] + b[1] * c[1] + b[2] * c[2];
            let got = srgb8(&f, x, y);
            assert!(
                got[0] == got[1] && got[1] == got[2],
                "grey stays grey: {got:?}"
            );
            assert_code(got[0], expected, &format!("pixel ({x}, {y})"));
            codes.insert(got[0]);
            checked += 1;
        }
    }
    assert!(checked > 300, "only {checked} interior pixels");
    assert!(
        codes.len() > 40,
        "only {} distinct values: not interpolated",
        codes.len()
    );
    // The centroid is the average, 0.5, in linear terms (sRGB-space interpolation would give
    // about 0.21).
    let (x, y) = pixel_of(Vec3::new(0.0, -1.0 / 3.0, 0.0), W, H);
    let v = f.image.at(x, y).x;
    assert!((v - 0.5).abs() < 0.03, "centroid {v}");
}

#[test]
fn nearer_triangles_hide_farther_ones() {
    let near = |m: &mut BakedMesh| quad(m, -0.5, -0.5, 0.5, 0.5, 0.5, [0.0, 1.0, 0.0]);
    let far = |m: &mut BakedMesh| quad(m, -1.5, -1.5, 1.5, 1.5, -1.0, [1.0, 0.0, 0.0]);
    let mut near_first = BakedMesh::default();
    near(&mut near_first);
    far(&mut near_first);
    let mut far_first = BakedMesh::default();
    far(&mut far_first);
    near(&mut far_first);
    for m in [&near_first, &far_first] {
        let f = render(m, W, H, false);
        let (x, y) = pixel_of(Vec3::ZERO, W, H);
        assert_eq!(srgb8(&f, x, y), [0, 255, 0], "the near square is in front");
        let (x, y) = pixel_of(Vec3::new(1.0, 0.0, -1.0), W, H);
        assert_eq!(srgb8(&f, x, y), [255, 0, 0], "the far square around it");
        let (x, y) = pixel_of(Vec3::new(0.0, -1.2, -1.0), W, H);
        assert_eq!(srgb8(&f, x, y), [255, 0, 0]);
    }
    // Draw order does not matter.
    assert_eq!(
        render(&near_first, W, H, false).srgb8,
        render(&far_first, W, H, false).srgb8
    );
}

#[test]
fn back_faces_are_drawn() {
    let mut m = BakedMesh::default();
    // Counter-clockwise as seen from the camera (front-facing) on the left...
    let a = push_vertex(&mut m, [-1.5, -1.0, 0.0], [1.0, 0.0, 0.0]);
    let b = push_vertex(&mut m, [-0.3, -1.0, 0.0], [1.0, 0.0, 0.0]);
    let c = push_vertex(&mut m, [-0.9, 1.0, 0.0], [1.0, 0.0, 0.0]);
    m.triangles.push([a, b, c]);
    // ...clockwise (back-facing) on the right.
    let a = push_vertex(&mut m, [0.3, -1.0, 0.0], [0.0, 0.0, 1.0]);
    let b = push_vertex(&mut m, [1.5, -1.0, 0.0], [0.0, 0.0, 1.0]);
    let c = push_vertex(&mut m, [0.9, 1.0, 0.0], [0.0, 0.0, 1.0]);
    m.triangles.push([a, c, b]);
    let f = render(&m, W, H, false);
    let (x, y) = pixel_of(Vec3::new(-0.9, -0.5, 0.0), W, H);
    assert_eq!(srgb8(&f, x, y), [255, 0, 0]);
    let (x, y) = pixel_of(Vec3::new(0.9, -0.5, 0.0), W, H);
    assert_eq!(
        srgb8(&f, x, y),
        [0, 0, 255],
        "the back-facing triangle is not culled"
    );
}

#[test]
fn odd_film_size_rows_are_unpadded() {
    // 37 × 4 bytes per row is not a multiple of 256: the read-back rows are padded, and a
    // wrong stride would shear the image.
    let (w, h) = (37, 23);
    let mut m = BakedMesh::default();
    quad(&mut m, 0.3, -5.0, 5.0, 5.0, 0.0, [0.5, 0.5, 0.5]);
    let f = render(&m, w, h, false);
    assert_eq!(f.srgb8.len(), 3 * (w * h) as usize);
    let edge = project(Vec3::new(0.3, 0.0, 0.0), w, h).x;
    let first_lit = (edge - 0.5).ceil() as u32;
    for y in 0..h {
        for x in 0..w {
            let lit = f.image.at(x, y) != Vec3::ZERO;
            assert_eq!(lit, x >= first_lit, "pixel ({x}, {y}), edge at {edge}");
            if lit {
                assert_code(srgb8(&f, x, y)[0], 0.5, "grey 0.5");
            }
        }
    }
}

#[test]
fn false_colour_maps_luminance_to_a_ramp() {
    let mut m = BakedMesh::default();
    // Luminance 0.01, 0.1 and 1: the ends and the middle of the log-scale ramp.
    quad(&mut m, -2.2, -1.0, -0.8, 1.0, 0.0, [0.01; 3]);
    quad(&mut m, -0.6, -1.0, 0.6, 1.0, 0.0, [0.1; 3]);
    quad(&mut m, 0.8, -1.0, 2.2, 1.0, 0.0, [1.0; 3]);
    let f = render(&m, W, H, true);
    let at = |x: f32| {
        let (x, y) = pixel_of(Vec3::new(x, 0.0, 0.0), W, H);
        srgb8(&f, x, y)
    };
    let (low, mid, high) = (at(-1.5), at(0.0), at(1.5));
    // Turbo: dark at the bottom, green-yellow in the middle, red at the top.
    assert!(
        low.iter().all(|&c| c < 64),
        "low luminance is dark: {low:?}"
    );
    assert!(
        mid[1] > mid[0] && mid[1] > mid[2],
        "middle is green: {mid:?}"
    );
    assert!(
        high[0] > high[1] && high[0] > high[2],
        "high luminance is red: {high:?}"
    );
    // The background stays black, and plain mode is grey.
    assert_eq!(srgb8(&f, 0, 0), [0, 0, 0]);
    let plain = render(&m, W, H, false);
    let (x, y) = pixel_of(Vec3::new(1.5, 0.0, 0.0), W, H);
    assert_eq!(srgb8(&plain, x, y), [255, 255, 255]);
}

#[test]
fn decoded_values_use_the_srgb_eotf() {
    let mut m = BakedMesh::default();
    quad(&mut m, -5.0, -5.0, 5.0, 5.0, 0.0, [0.18, 0.5, 0.75]);
    let f = render(&m, 8, 6, false);
    let t = srgb8_to_linear_table();
    for (i, p) in f.image.pixels.iter().enumerate() {
        let c = &f.srgb8[3 * i..3 * i + 3];
        assert_eq!(
            p.to_array(),
            [t[c[0] as usize], t[c[1] as usize], t[c[2] as usize]]
        );
        assert_code(c[0], 0.18, "red");
        assert_code(c[1], 0.5, "green");
        assert_code(c[2], 0.75, "blue");
    }
}

#[test]
fn empty_mesh_and_non_finite_colours_give_black() {
    let f = render(&BakedMesh::default(), 16, 12, false);
    assert!(f.srgb8.iter().all(|&b| b == 0));
    let mut m = BakedMesh::default();
    quad(
        &mut m,
        -5.0,
        -5.0,
        5.0,
        5.0,
        0.0,
        [f32::NAN, f32::INFINITY, 0.5],
    );
    let f = render(&m, 16, 12, false);
    let c = srgb8(&f, 8, 6);
    assert_eq!(
        (c[0], c[1]),
        (0, 0),
        "non-finite colours are drawn black: {c:?}"
    );
    assert_code(c[2], 0.5, "finite channel");
}

#[test]
fn bad_input_is_an_input_error() {
    let mut m = BakedMesh::default();
    quad(&mut m, -1.0, -1.0, 1.0, 1.0, 0.0, [1.0; 3]);
    let err = |r: Result<Frame, ViewerError>| match r {
        Err(e @ ViewerError::Input(_)) => e.to_string(),
        Err(e) => panic!("expected an input error, got {e}"),
        Ok(_) => panic!("expected an input error"),
    };
    let e = err(gpu().render(&m, &camera(), 0, 10, false));
    assert!(e.contains("film size 0x10"), "{e}");
    let mut bad = m.clone();
    bad.triangles.push([0, 1, 99]);
    let e = err(gpu().render(&bad, &camera(), 8, 8, false));
    assert!(e.contains("vertex 99"), "{e}");
    let mut cam = camera();
    cam.at = cam.eye;
    let e = err(gpu().render(&m, &cam, 8, 8, false));
    assert!(e.contains("does not define a view"), "{e}");
}
