//! The C API end to end: builds the kernel as a static library with its `capi` feature
//! (`cargo build -p ember-capi --release`), compiles tests/capi/cornell.c against it and
//! kernel/include/ember.h with the system C compiler (`$CC` or `cc`), runs it (it checks the
//! ABI version, renders the determinism Cornell box, with every material and textures, from
//! two pthreads with each path tracer, the light tracer and BDPT, whose splats each thread adds
//! to its own buffer before they are merged, and bakes a few points), and checks that every
//! array it built and every pixel, splat sum and baked value it produced is bit-identical to
//! what the Rust API computes from the same arrays (tests/determinism), and that its rendering
//! threads stayed within half of `EMBER_STACK_BYTES`.

use ember_determinism::{
    bake_point, render_pixel_rgb, render_splat_image, resolve_pixel, Scene, BAKE_ESTIMATORS,
    BAKE_POINTS, HEIGHT, INTEGRATORS, MATERIALS, PIXELS, SPLAT_INTEGRATORS, TEXELS, TEXTURES,
    TRIANGLES, VERTICES, WIDTH,
};
use ember_kernel::bvh::{self, BvhNode, WIDTH as WIDE_WIDTH};
use ember_kernel::geometry::GROUP_WIDTH;
use std::path::{Path, PathBuf};
use std::process::Command;

fn run(cmd: &mut Command) -> String {
    let out = cmd
        .output()
        .unwrap_or_else(|e| panic!("cannot run {cmd:?}: {e}"));
    assert!(
        out.status.success(),
        "{cmd:?} failed ({}):\n{}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Cargo's target directory (as `cargo metadata` reports it, so `CARGO_TARGET_DIR` and config
/// files are honoured).
fn target_dir(cargo: &str, root: &Path) -> PathBuf {
    let meta = run(Command::new(cargo).current_dir(root).args([
        "metadata",
        "--format-version",
        "1",
        "--no-deps",
    ]));
    let key = "\"target_directory\":\"";
    let start = meta.find(key).expect("target_directory in cargo metadata") + key.len();
    let end = start + meta[start..].find('"').expect("end of target_directory");
    PathBuf::from(meta[start..end].replace("\\\\", "\\"))
}

/// Reads the little-endian dump cornell.c writes.
struct Reader(Vec<u8>, usize);

impl Reader {
    fn u32(&mut self) -> u32 {
        let v = u32::from_le_bytes(self.0[self.1..self.1 + 4].try_into().unwrap());
        self.1 += 4;
        v
    }
    fn u32s(&mut self, n: usize) -> Vec<u32> {
        (0..n).map(|_| self.u32()).collect()
    }
    fn i64s(&mut self, n: usize) -> Vec<i64> {
        (0..n)
            .map(|_| {
                let v = i64::from_le_bytes(self.0[self.1..self.1 + 8].try_into().unwrap());
                self.1 += 8;
                v
            })
            .collect()
    }
    fn bytes(&mut self, n: usize) -> Vec<u8> {
        let v = self.0[self.1..self.1 + n].to_vec();
        self.1 += n;
        v
    }
    /// Floats as bit patterns, so comparisons are bitwise.
    fn f32_bits(&mut self, n: usize) -> Vec<u32> {
        self.u32s(n)
    }
}

/// The bytes `ember_build_accel` documents for the scene's wide tree (little-endian): a
/// 64-byte header ("EMBA", layout 1, node width, group width, node count, order length, group
/// count, triangle count, zeros), the nodes (each lane's `lo`, `hi` per axis, children, counts,
/// zero padding), the leaf order, zeros up to a 16-byte boundary and the triangle groups.
fn accel_bytes(scene: &Scene) -> Vec<u8> {
    let nodes = &scene.bvh_nodes[..scene.bvh_node_count];
    let order = &scene.bvh_wide_order[..scene.bvh_wide_order_len];
    let groups = &scene.bvh_leaf_groups[..order.len() / GROUP_WIDTH];
    let mut b = Vec::new();
    let words = |b: &mut Vec<u8>, w: &[u32]| w.iter().for_each(|v| b.extend(v.to_le_bytes()));
    words(
        &mut b,
        &[
            u32::from_le_bytes(*b"EMBA"),
            1,
            WIDE_WIDTH as u32,
            GROUP_WIDTH as u32,
            nodes.len() as u32,
            order.len() as u32,
            groups.len() as u32,
            TRIANGLES as u32,
        ],
    );
    b.resize(64, 0);
    for n in nodes {
        for corner in [&n.lo, &n.hi] {
            words(
                &mut b,
                &corner
                    .iter()
                    .flatten()
                    .map(|c| c.to_bits())
                    .collect::<Vec<_>>(),
            );
        }
        words(&mut b, &n.child);
        n.count.iter().for_each(|c| b.extend(c.to_le_bytes()));
        b.resize(b.len() + 2 * WIDE_WIDTH, 0);
    }
    words(&mut b, order);
    b.resize(b.len().next_multiple_of(16), 0);
    for g in groups {
        words(
            &mut b,
            &g.v.iter()
                .flatten()
                .flatten()
                .map(|c| c.to_bits())
                .collect::<Vec<_>>(),
        );
    }
    b
}

fn bits3(v: &[[f32; 3]]) -> Vec<u32> {
    v.iter().flatten().map(|c| c.to_bits()).collect()
}

#[test]
fn c_program_renders_bit_identically_to_the_rust_api() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    run(Command::new(&cargo).current_dir(&root).args([
        "build",
        "--quiet",
        "--release",
        "-p",
        "ember-capi",
    ]));
    let lib = target_dir(&cargo, &root).join("release/libember_capi.a");
    assert!(lib.is_file(), "{} was not built", lib.display());

    let dir = std::env::temp_dir().join(format!("ember-capi-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let exe = dir.join("cornell");
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    run(Command::new(&cc)
        .args([
            "-std=c11",
            "-O2",
            "-Wall",
            "-Wextra",
            "-Wpedantic",
            "-Werror",
            "-pthread",
        ])
        .arg("-I")
        .arg(root.join("kernel/include"))
        .arg(root.join("tests/capi/cornell.c"))
        .arg(&lib)
        .args(["-lpthread", "-ldl", "-lm", "-o"])
        .arg(&exe));
    let dump = dir.join("cornell.bin");
    let printed = run(Command::new(&exe).arg(&dump));
    let mut r = Reader(std::fs::read(&dump).unwrap(), 0);
    std::fs::remove_dir_all(&dir).ok();

    // The arrays: the C program built the same scene as tests/determinism.
    let scene = Scene::new();
    let view = scene.view();
    assert_eq!(r.u32() as usize, VERTICES);
    assert_eq!(
        r.f32_bits(3 * VERTICES),
        bits3(&scene.positions.map(|p| p.to_array()))
    );
    assert_eq!(
        r.f32_bits(3 * VERTICES),
        bits3(&scene.normals.map(|n| n.to_array()))
    );
    let uvs: Vec<u32> = scene
        .uvs
        .iter()
        .flat_map(|uv| uv.to_array().map(f32::to_bits))
        .collect();
    assert_eq!(r.f32_bits(2 * VERTICES), uvs, "texture coordinates");
    assert_eq!(r.u32() as usize, TRIANGLES);
    let tris: Vec<u32> = scene.triangles.iter().flatten().copied().collect();
    assert_eq!(r.u32s(3 * TRIANGLES), tris);
    assert_eq!(r.u32s(TRIANGLES), scene.triangle_materials);
    // The textures and texels the C program hands ember are the Rust scene's.
    assert_eq!(r.u32() as usize, TEXTURES.len());
    for (i, t) in TEXTURES.iter().enumerate() {
        let mut expect = vec![t.width, t.height, t.first_texel];
        expect.extend(t.uv_scale.to_array().map(f32::to_bits));
        expect.extend(t.uv_offset.to_array().map(f32::to_bits));
        assert_eq!(r.u32s(7), expect, "texture {i}");
    }
    assert_eq!(r.u32() as usize, TEXELS.len());
    assert_eq!(r.f32_bits(3 * TEXELS.len()), bits3(&TEXELS), "texels");
    assert_eq!(bits3(&scene.texels.map(|t| t.to_array())), bits3(&TEXELS));
    // The emitter table and the BVH the C API built equal the kernel builders' output.
    let ne = r.u32() as usize;
    assert_eq!(ne, scene.emitter_count, "emitter count");
    assert_eq!(r.u32s(ne), view.emitter_triangles, "emitter triangles");
    let cdf: Vec<u32> = view.emitter_cdf.iter().map(|c| c.to_bits()).collect();
    assert_eq!(r.f32_bits(ne), cdf, "emitter cdf");
    // The C API traces the binary tree as built; the Rust view below traces its wide
    // collapse, so the pixel comparison also checks that both give the same image.
    let mut binary = vec![BvhNode::default(); bvh::max_nodes(TRIANGLES)];
    let mut order = vec![0; TRIANGLES];
    let used =
        bvh::build_triangles(&scene.positions, &scene.triangles, &mut binary, &mut order).unwrap();
    assert_eq!(order, scene.bvh_prim_order);
    let nn = r.u32() as usize;
    assert_eq!(nn, used, "BVH node count");
    for (i, node) in binary[..used].iter().enumerate() {
        let mut expect: Vec<u32> = node.min.iter().map(|c| c.to_bits()).collect();
        expect.push(node.offset);
        expect.extend(node.max.iter().map(|c| c.to_bits()));
        expect.push(u32::from(node.count) | u32::from(node.axis) << 16 | u32::from(node.pad) << 24);
        assert_eq!(r.u32s(8), expect, "BVH node {i}");
    }
    assert_eq!(
        r.u32s(TRIANGLES),
        scene.bvh_prim_order,
        "BVH triangle order"
    );
    // The acceleration structure the C program traced is, byte for byte, the wide tree, leaf
    // order and triangle groups the command line traces (tests/determinism builds them).
    let accel_used = r.u32() as usize;
    let accel = r.bytes(accel_used);
    assert_eq!(accel, accel_bytes(&scene), "acceleration structure");

    // Every pixel of the three renders (two threads, 8x8 tiles in C; one pixel at a time here).
    assert_eq!((r.u32(), r.u32()), (WIDTH, HEIGHT));
    for integrator in INTEGRATORS {
        let c = r.f32_bits(3 * (WIDTH * HEIGHT) as usize);
        let mut rust = Vec::new();
        for y in 0..HEIGHT {
            for x in 0..WIDTH {
                rust.push(render_pixel_rgb(&view, integrator, x, y));
            }
        }
        let rust = bits3(&rust);
        let differ = c.iter().zip(&rust).filter(|(a, b)| a != b).count();
        assert_eq!(
            differ,
            0,
            "{integrator:?}: {differ} of {} channels differ",
            c.len()
        );
        // Not a black image, so that the comparison means something (the implicit render at
        // 4 spp finds the small light through a few paths only).
        let lit = rust.iter().filter(|&&b| f32::from_bits(b) > 0.0).count();
        assert!(
            lit > rust.len() / 20,
            "{integrator:?}: only {lit} channels > 0"
        );
    }
    // The baked values.
    assert_eq!(r.u32() as usize, BAKE_POINTS.len());
    for estimator in BAKE_ESTIMATORS {
        let c = r.f32_bits(3 * BAKE_POINTS.len());
        let rust: Vec<[f32; 3]> = (0..BAKE_POINTS.len())
            .map(|i| bake_point(&view, estimator, i))
            .collect();
        assert_eq!(c, bits3(&rust), "{estimator:?} bake");
        // Every point gathers light, so that the comparison means something.
        for (i, v) in rust.iter().enumerate() {
            assert!(
                v.iter().any(|&c| c > 0.0),
                "{estimator:?}: point {i} baked {v:?}"
            );
        }
    }
    // The splatting renders: the sums of each tile (two threads, 8x8 tiles in C), the splat
    // buffers of the two threads merged, and the resolved image, each equal to a single-thread
    // render of the whole film into one buffer in Rust.
    assert_eq!(r.u32() as usize, SPLAT_INTEGRATORS.len());
    let mut rust_sums = Vec::new();
    let mut rust_splats = Vec::new();
    for &integrator in &SPLAT_INTEGRATORS {
        let (mut sums, mut splats) = ([[0.0f32; 3]; PIXELS], [[0i64; 3]; PIXELS]);
        render_splat_image(&view, integrator, &mut sums, &mut splats);
        rust_sums.push(sums);
        rust_splats.push(splats);
    }
    for (k, integrator) in SPLAT_INTEGRATORS.iter().enumerate() {
        assert_eq!(
            r.f32_bits(3 * PIXELS),
            bits3(&rust_sums[k]),
            "{integrator:?} sums"
        );
    }
    for (k, integrator) in SPLAT_INTEGRATORS.iter().enumerate() {
        let rust: Vec<i64> = rust_splats[k].iter().flatten().copied().collect();
        let c = r.i64s(3 * PIXELS);
        let differ = c.iter().zip(&rust).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "{integrator:?}: {differ} splat sums differ");
        // Light lands as splats on most pixels, so that the comparison means something.
        let splatted = rust_splats[k]
            .iter()
            .filter(|s| s.iter().any(|&c| c > 0))
            .count();
        assert!(
            splatted > PIXELS / 2,
            "{integrator:?}: {splatted} pixels splatted"
        );
    }
    for (k, integrator) in SPLAT_INTEGRATORS.iter().enumerate() {
        let rust: Vec<[f32; 3]> = rust_sums[k]
            .iter()
            .zip(&rust_splats[k])
            .map(|(sum, s)| resolve_pixel(*sum, *s))
            .collect();
        assert_eq!(r.f32_bits(3 * PIXELS), bits3(&rust), "{integrator:?} image");
    }
    // The rendering threads ran on painted stacks of EMBER_STACK_BYTES; cornell.c refuses more
    // than half of it, and the measurement must have seen at least the 60 KiB material table.
    let header = std::fs::read_to_string(root.join("kernel/include/ember.h")).unwrap();
    let stack_bytes: usize = header
        .lines()
        .find_map(|l| l.strip_prefix("#define EMBER_STACK_BYTES "))
        .expect("EMBER_STACK_BYTES in ember.h")
        .trim()
        .parse()
        .unwrap();
    let used = r.u32() as usize;
    eprintln!("cornell.c: a rendering thread used {used} of its {stack_bytes} stack bytes");
    assert!(
        used > 60 * 1024 && 2 * used <= stack_bytes,
        "{used} of {stack_bytes}"
    );
    assert_eq!(r.1, r.0.len(), "trailing bytes in the dump");

    // The scene compared has every material: each kind, smooth and rough conductors and
    // dielectrics, a textured diffuse and a textured Phong material, each on some triangle.
    use ember_determinism::{CONDUCTOR, DIELECTRIC, DIFFUSE, MIXTURE, PHONG};
    use ember_kernel::texture::NO_TEXTURE;
    let has = |f: &dyn Fn(&ember_determinism::MaterialDesc) -> bool| MATERIALS.iter().any(f);
    assert!(has(&|m| m.kind == CONDUCTOR && m.alpha == 0.0));
    assert!(has(&|m| m.kind == CONDUCTOR && m.alpha >= 0.1));
    assert!(has(&|m| m.kind == DIELECTRIC
        && m.alpha == 0.0
        && m.ior == 1.5));
    assert!(has(&|m| m.kind == DIELECTRIC && m.alpha >= 0.1));
    assert!(has(&|m| m.kind == DIFFUSE && m.kd_texture != NO_TEXTURE));
    assert!(has(&|m| m.kind == PHONG
        && m.kd_texture != NO_TEXTURE
        && m.ks_texture != NO_TEXTURE));
    assert!(has(&|m| m.kind == MIXTURE));
    for i in 0..MATERIALS.len() as u32 {
        assert!(
            scene.triangle_materials.contains(&i),
            "material {i} is on no triangle"
        );
    }

    // The hashes it printed are the determinism hashes.
    let h = ember_determinism::hashes();
    assert_eq!(
        printed,
        format!(
            "render {:016x}\nbake {:016x}\nsplat {:016x}\n",
            h.render, h.bake, h.splat
        )
    );
}
