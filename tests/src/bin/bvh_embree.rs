//! ember's BVH on the bench-embree scenes and rays (`shared/bench-embree`), checked ray by ray
//! against Embree's hits and timed as bench-embree's `bench.py` times Embree.
//!
//!     ember-bvh-embree DATA_DIR [--scenes cbox,sphere_1k] [--threads 1,2] [--passes 3]
//!                      [--t-tol 1e-4] [--json FILE]
//!
//! DATA_DIR is a bench-embree directory after `make_data.py` (and, for the check,
//! `bench/embree/embree_ref.py`): `scenes/manifest.json` names each scene's OBJ,
//! `scenes/bin/<scene>_{V,F}.npy` hold the triangles Embree was given (the OBJ parse is checked
//! against them bit for bit), `rays/<scene>_<set>_{origins,dirs[,tfar]}.npy` the rays and
//! `results/ref[-robust]/` Embree's per-ray results.
//!
//! Per scene: the BVH is built three times as the host builds it (`SceneData::build_bvh`,
//! triangle bounds included; one thread), and the kernel data it traverses is counted (nodes,
//! prim order, triangle indices, positions). Per ray set and thread count: one warm-up pass
//! and `--passes` timed passes over all rays, one ray at a time through
//! `SceneView::intersect` / `SceneView::occluded`, each writing its result per ray (t and
//! triangle, or occluded); 2 threads pull 4096-ray chunks. Mrays/s is from the median pass.
//! The last pass is compared with Embree's: hit/miss (or occluded) disagreement, and for rays
//! both hit, |t_ember − t_embree| > `--t-tol` · (t + max|o|), i.e. relative to the size of the
//! coordinates whose f32 rounding sets the error of t (a pure relative test would flag the rays
//! that start within 1e-5 of a wall). Each mismatch is classified by the hit that one side
//! found and the other did not (or the nearer one): near a triangle edge, grazing, an interior
//! hit so close to the origin that ember's conservative t > 0 test rejects it, or other.
//!
//! With `--serve` (one scene), it builds the BVH once, prints `ready`, and then times one pass
//! per line read from stdin, `SET QUERY THREADS` (e.g. `camera INTERSECT 1`), answering
//! `SECONDS RESULTS_HASH`; `bench/embree/lockstep.py` drives it pass by pass against Embree
//! (or another build), so that both sides of a ratio are measured within a second of each
//! other.

use ember_cli::mesh::SceneData;
use ember_kernel::geometry::{intersect_triangle, Ray};
use ember_kernel::scene::SceneView;
use ember_kernel::Vec3;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

const SCENES: [&str; 5] = [
    "cbox",
    "sphere_1k",
    "sphere_10k",
    "sphere_100k",
    "sphere_1m",
];
/// (ray set, query) as in bench.py's `QUERIES`.
const QUERIES: [(&str, Query); 4] = [
    ("camera", Query::Intersect),
    ("incoherent", Query::Intersect),
    ("shadow", Query::Intersect),
    ("shadow", Query::Occluded),
];
/// Rays a thread takes at a time (as the native Embree harness of bench-embree).
const CHUNK: usize = 4096;
/// A hit point closer than this (in barycentric coordinates) to an edge counts as "edge".
const EDGE_BARY: f64 = 1e-5;
/// A ray with |cos| to the triangle normal below this (about 1.1°) counts as "grazing".
const GRAZING_COS: f64 = 2e-2;

#[derive(Clone, Copy, PartialEq)]
enum Query {
    Intersect,
    Occluded,
}

impl Query {
    fn name(self) -> &'static str {
        match self {
            Query::Intersect => "INTERSECT",
            Query::Occluded => "OCCLUDED",
        }
    }
}

type Res<T> = Result<T, String>;

struct Args {
    data: PathBuf,
    scenes: Vec<String>,
    threads: Vec<usize>,
    passes: usize,
    t_tol: f64,
    json: Option<PathBuf>,
    serve: bool,
}

fn parse_args() -> Res<Args> {
    let mut args = Args {
        data: PathBuf::new(),
        scenes: SCENES.iter().map(|s| s.to_string()).collect(),
        threads: vec![1, 2],
        passes: 3,
        t_tol: 1e-4,
        json: None,
        serve: false,
    };
    let mut it = std::env::args().skip(1);
    let mut data = None;
    while let Some(a) = it.next() {
        let mut value = || it.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--scenes" => args.scenes = value()?.split(',').map(str::to_string).collect(),
            "--threads" => {
                args.threads = value()?
                    .split(',')
                    .map(|t| t.parse().map_err(|e| format!("--threads: {e}")))
                    .collect::<Res<_>>()?;
            }
            "--passes" => args.passes = value()?.parse().map_err(|e| format!("--passes: {e}"))?,
            "--t-tol" => args.t_tol = value()?.parse().map_err(|e| format!("--t-tol: {e}"))?,
            "--json" => args.json = Some(value()?.into()),
            "--serve" => args.serve = true,
            "-h" | "--help" => {
                println!("usage: ember-bvh-embree DATA_DIR [--scenes a,b] [--threads 1,2] [--passes 3] [--t-tol 1e-4] [--json FILE] [--serve]");
                std::process::exit(0);
            }
            _ if a.starts_with('-') => return Err(format!("unknown option {a}")),
            _ if data.is_none() => data = Some(PathBuf::from(a)),
            _ => return Err(format!("unexpected argument {a}")),
        }
    }
    args.data = data.ok_or("usage: ember-bvh-embree DATA_DIR [options] (--help)")?;
    if args.passes == 0 || args.threads.contains(&0) {
        return Err("--passes and --threads must be positive".into());
    }
    if args.serve && args.scenes.len() != 1 {
        return Err("--serve needs exactly one scene (--scenes NAME)".into());
    }
    Ok(args)
}

// --------------------------------------------------------------------------- input files

fn read(path: &Path) -> Res<Vec<u8>> {
    std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))
}

/// A C-order little-endian `.npy` array of 4-byte elements with dtype `descr` (`<f4`, `<u4`):
/// its shape and its elements' bytes.
fn read_npy(path: &Path, descr: &str) -> Res<(Vec<usize>, Vec<[u8; 4]>)> {
    let bytes = read(path)?;
    let bad = |what: &str| format!("{}: {what}", path.display());
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err(bad("not an .npy file"));
    }
    let (header_len, start) = match bytes[6] {
        1 => (usize::from(u16::from_le_bytes([bytes[8], bytes[9]])), 10),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
        _ => return Err(bad("unsupported .npy version")),
    };
    let header = bytes
        .get(start..start + header_len)
        .and_then(|h| std::str::from_utf8(h).ok())
        .ok_or_else(|| bad("bad header"))?;
    if !header.contains(&format!("'descr': '{descr}'")) {
        return Err(bad(&format!("dtype is not {descr}: {header}")));
    }
    if !header.contains("'fortran_order': False") {
        return Err(bad("Fortran-order array"));
    }
    let shape = header
        .split("'shape': (")
        .nth(1)
        .and_then(|s| s.split(')').next())
        .ok_or_else(|| bad("no shape"))?;
    let shape: Vec<usize> = shape
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().map_err(|_| bad("bad shape")))
        .collect::<Res<_>>()?;
    let data = &bytes[start + header_len..];
    if data.len() != 4 * shape.iter().product::<usize>() {
        return Err(bad("data size does not match the shape"));
    }
    Ok((
        shape,
        data.chunks_exact(4)
            .map(|c| [c[0], c[1], c[2], c[3]])
            .collect(),
    ))
}

fn read_npy_f32(path: &Path) -> Res<(Vec<usize>, Vec<f32>)> {
    let (shape, data) = read_npy(path, "<f4")?;
    Ok((shape, data.into_iter().map(f32::from_le_bytes).collect()))
}

/// An `(n, 3)` float32 array as vectors.
fn read_vec3s(path: &Path) -> Res<Vec<Vec3>> {
    let (shape, v) = read_npy_f32(path)?;
    if shape.len() != 2 || shape[1] != 3 {
        return Err(format!("{}: shape {shape:?} is not (n, 3)", path.display()));
    }
    Ok(v.chunks_exact(3).map(Vec3::from_slice).collect())
}

/// The OBJ path of `scene` from make_data.py's manifest.json (`"<scene>": {"obj": "..."`).
fn manifest_obj(data: &Path, scene: &str) -> Res<PathBuf> {
    let path = data.join("scenes/manifest.json");
    let text = String::from_utf8(read(&path)?).map_err(|e| e.to_string())?;
    let entry = text
        .split(&format!("\"{scene}\": {{"))
        .nth(1)
        .ok_or_else(|| format!("{}: no scene {scene}", path.display()))?;
    let obj = entry
        .split("\"obj\": \"")
        .nth(1)
        .and_then(|s| s.split('"').next())
        .ok_or_else(|| format!("{}: no obj for {scene}", path.display()))?;
    Ok(PathBuf::from(obj))
}

/// `v` and `f` lines of an OBJ, as make_data.py's `load_obj` reads them: `v/vt/vn` and
/// negative indices, polygons fan-triangulated (v0, vk, vk+1).
fn load_obj(path: &Path) -> Res<(Vec<Vec3>, Vec<[u32; 3]>)> {
    let text = String::from_utf8(read(path)?).map_err(|e| e.to_string())?;
    let (mut positions, mut triangles) = (Vec::new(), Vec::new());
    let bad = |line: usize| format!("{}:{}: malformed line", path.display(), line + 1);
    for (ln, line) in text.lines().enumerate() {
        if let Some(rest) = line.strip_prefix("v ") {
            let c: Vec<f32> = rest
                .split_whitespace()
                .take(3)
                .map(|s| s.parse().map_err(|_| bad(ln)))
                .collect::<Res<_>>()?;
            if c.len() != 3 {
                return Err(bad(ln));
            }
            positions.push(Vec3::from_slice(&c));
        } else if let Some(rest) = line.strip_prefix("f ") {
            let idx: Vec<u32> = rest
                .split_whitespace()
                .map(|tok| {
                    let i: i64 = tok
                        .split('/')
                        .next()
                        .unwrap_or("")
                        .parse()
                        .map_err(|_| bad(ln))?;
                    let i = if i > 0 {
                        i - 1
                    } else {
                        positions.len() as i64 + i
                    };
                    u32::try_from(i).map_err(|_| bad(ln))
                })
                .collect::<Res<_>>()?;
            for k in 1..idx.len().saturating_sub(1) {
                triangles.push([idx[0], idx[k], idx[k + 1]]);
            }
        }
    }
    Ok((positions, triangles))
}

/// The scene's OBJ, checked against the float32/uint32 arrays Embree was given.
fn load_scene(data: &Path, scene: &str) -> Res<(Vec<Vec3>, Vec<[u32; 3]>)> {
    let obj = manifest_obj(data, scene)?;
    let (positions, triangles) = load_obj(&obj)?;
    let bin = data.join("scenes/bin");
    let v = read_vec3s(&bin.join(format!("{scene}_V.npy")))?;
    let (shape, f) = read_npy(&bin.join(format!("{scene}_F.npy")), "<u4")?;
    let f: Vec<u32> = f.into_iter().map(u32::from_le_bytes).collect();
    let same_positions = v.len() == positions.len()
        && v.iter()
            .zip(&positions)
            .all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits));
    let same_triangles =
        shape == [triangles.len(), 3] && f.chunks_exact(3).zip(&triangles).all(|(a, b)| a == b);
    if !same_positions || !same_triangles {
        return Err(format!(
            "{}: the OBJ parse differs from scenes/bin/{scene}_{{V,F}}.npy (positions same: {same_positions}, triangles same: {same_triangles})",
            obj.display()
        ));
    }
    Ok((positions, triangles))
}

fn load_rays(data: &Path, scene: &str, set: &str) -> Res<Vec<Ray>> {
    let base = data.join(format!("rays/{scene}_{set}"));
    let file = |s: &str| PathBuf::from(format!("{}_{s}.npy", base.display()));
    let o = read_vec3s(&file("origins"))?;
    let d = read_vec3s(&file("dirs"))?;
    let t_max = if set == "shadow" {
        read_npy_f32(&file("tfar"))?.1
    } else {
        vec![f32::INFINITY; o.len()]
    };
    if d.len() != o.len() || t_max.len() != o.len() {
        return Err(format!("{}: ray arrays differ in length", base.display()));
    }
    Ok((0..o.len())
        .map(|i| Ray {
            o: o[i],
            d: d[i],
            t_max: t_max[i],
        })
        .collect())
}

/// Embree's result per ray from `results/<sub>/`, or `None` if its files are missing.
fn load_ref(data: &Path, sub: &str, scene: &str, set: &str, q: Query) -> Res<Option<Vec<Out>>> {
    let base = data.join(format!("results/{sub}/{scene}_{set}_{}", q.name()));
    let file = |s: &str| PathBuf::from(format!("{}_{s}", base.display()));
    let words = |p: PathBuf| -> Res<Option<Vec<[u8; 4]>>> {
        if !p.exists() {
            return Ok(None);
        }
        let b = read(&p)?;
        Ok(Some(
            b.chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect(),
        ))
    };
    Ok(match q {
        Query::Intersect => {
            let (Some(prim), Some(t)) = (words(file("prim.i32"))?, words(file("t.f32"))?) else {
                return Ok(None);
            };
            Some(
                prim.iter()
                    .zip(&t)
                    .map(|(p, t)| Out {
                        t: f32::from_le_bytes(*t),
                        prim: i32::from_le_bytes(*p),
                    })
                    .collect(),
            )
        }
        Query::Occluded => {
            let p = file("occ.u8");
            if !p.exists() {
                return Ok(None);
            }
            Some(
                read(&p)?
                    .into_iter()
                    .map(|o| Out {
                        t: 0.0,
                        prim: if o != 0 { 0 } else { -1 },
                    })
                    .collect(),
            )
        }
    })
}

// --------------------------------------------------------------------------- tracing

/// One ray's result: the hit distance and triangle (`prim` −1 on a miss), or for OCCLUDED
/// `prim` 0 when occluded, −1 when not.
#[derive(Clone, Copy, Default, PartialEq)]
struct Out {
    t: f32,
    prim: i32,
}

const MISS: Out = Out { t: 0.0, prim: -1 };

fn trace_one(view: &SceneView<'_>, q: Query, r: &Ray) -> Out {
    match q {
        Query::Intersect => view.intersect(r).map_or(MISS, |h| Out {
            t: h.t,
            prim: h.triangle as i32,
        }),
        Query::Occluded => {
            if view.occluded(r) {
                Out { t: 0.0, prim: 0 }
            } else {
                MISS
            }
        }
    }
}

/// One pass over all rays on `threads` threads; returns its wall time in seconds.
fn trace(view: &SceneView<'_>, q: Query, rays: &[Ray], out: &mut [Out], threads: usize) -> f64 {
    let start = Instant::now();
    if threads == 1 {
        for (r, o) in rays.iter().zip(out.iter_mut()) {
            *o = trace_one(view, q, r);
        }
    } else {
        let work = Mutex::new(rays.chunks(CHUNK).zip(out.chunks_mut(CHUNK)));
        std::thread::scope(|s| {
            for _ in 0..threads {
                s.spawn(|| loop {
                    let next = work.lock().expect("work queue").next();
                    let Some((rays, out)) = next else { break };
                    for (r, o) in rays.iter().zip(out.iter_mut()) {
                        *o = trace_one(view, q, r);
                    }
                });
            }
        });
    }
    start.elapsed().as_secs_f64()
}

/// FNV-1a over every ray's (t bits, prim): equal results give equal hashes.
fn results_hash(out: &[Out]) -> u64 {
    out.iter()
        .flat_map(|o| {
            let [a, b, c, d] = o.t.to_bits().to_le_bytes();
            let [e, f, g, h] = o.prim.to_le_bytes();
            [a, b, c, d, e, f, g, h]
        })
        .fold(0xcbf2_9ce4_8422_2325, |h, byte| {
            (h ^ u64::from(byte)).wrapping_mul(0x0100_0000_01b3)
        })
}

// --------------------------------------------------------------------------- checking

/// Where a hit lies on its triangle: the smallest barycentric coordinate of `o + t·d` (f64)
/// and |cos| between the ray and the triangle's normal.
fn hit_geometry(view: &SceneView<'_>, r: &Ray, prim: u32, t: f32) -> (f64, f64) {
    let [a, b, c] = view.triangle_vertices(prim).map(|p| p.as_dvec3());
    let (o, d) = (r.o.as_dvec3(), r.d.as_dvec3());
    let p = o + d * f64::from(t);
    let n = (b - a).cross(c - a);
    let area = n.length_squared();
    if area == 0.0 {
        return (0.0, 0.0);
    }
    let w1 = (p - a).cross(c - a).dot(n) / area;
    let w2 = (b - a).cross(p - a).dot(n) / area;
    let min_bary = (1.0 - w1 - w2).min(w1).min(w2);
    let cos = n.dot(d).abs() / (area.sqrt() * d.length());
    (min_bary, cos)
}

#[derive(Default)]
struct Check {
    /// Rays where ember hit (or found occlusion) and Embree did not.
    ember_only: usize,
    /// Rays where Embree hit (or found occlusion) and ember did not.
    embree_only: usize,
    /// Both hit, relative t difference above the tolerance.
    t_diff: usize,
    /// Both hit at the same t (within the tolerance) on different triangles: a shared edge.
    same_t_other_prim: usize,
    /// Largest |Δt| / (t + max|o|) over rays both hit.
    max_rel_t: f64,
    /// Mismatches by their deciding hit: within [`EDGE_BARY`] of an edge; grazing (|cos| below
    /// [`GRAZING_COS`]); an interior hit found by Embree that ember's own triangle test rejects
    /// (t within its conservative bound of 0: the origin lies on the surface, to rounding);
    /// anything else.
    edge: usize,
    grazing: usize,
    t_bound: usize,
    other: usize,
    examples: Vec<String>,
}

impl Check {
    fn mismatches(&self) -> usize {
        self.ember_only + self.embree_only + self.t_diff
    }

    fn json(&self, rays: usize) -> String {
        format!(
            "{{\"mismatches\": {}, \"rate\": {:e}, \"ember_only\": {}, \"embree_only\": {}, \"t_diff\": {}, \"same_t_other_prim\": {}, \"max_rel_t\": {:e}, \"edge\": {}, \"grazing\": {}, \"t_bound\": {}, \"other\": {}}}",
            self.mismatches(),
            self.mismatches() as f64 / rays as f64,
            self.ember_only,
            self.embree_only,
            self.t_diff,
            self.same_t_other_prim,
            self.max_rel_t,
            self.edge,
            self.grazing,
            self.t_bound,
            self.other
        )
    }

    fn summary(&self, rays: usize) -> String {
        format!(
            "{} mismatches ({:.2e}): ember-only {}, Embree-only {}, t {}; same t other triangle {}; max |dt|/(t+|o|) {:.1e}; edge {}, grazing {}, t bound {}, other {}",
            self.mismatches(),
            self.mismatches() as f64 / rays as f64,
            self.ember_only,
            self.embree_only,
            self.t_diff,
            self.same_t_other_prim,
            self.max_rel_t,
            self.edge,
            self.grazing,
            self.t_bound,
            self.other
        )
    }
}

/// Compares ember's results with Embree's. `shadow_hits` are Embree's INTERSECT results on the
/// same shadow rays (the blocker of an occlusion only Embree found).
fn check(
    view: &SceneView<'_>,
    q: Query,
    rays: &[Ray],
    ember: &[Out],
    embree: &[Out],
    shadow_hits: Option<&[Out]>,
    t_tol: f64,
) -> Check {
    let mut c = Check::default();
    for (i, ((r, e), x)) in rays.iter().zip(ember).zip(embree).enumerate() {
        let (eh, xh) = (e.prim >= 0, x.prim >= 0);
        // The hit that decides the mismatch: the one only one side found, or the nearer one.
        let deciding: Option<(u32, f32, &str)> = match (eh, xh) {
            (false, false) => None,
            (true, false) => {
                c.ember_only += 1;
                Some((e.prim as u32, e.t, "ember only"))
            }
            (false, true) => {
                c.embree_only += 1;
                Some((x.prim as u32, x.t, "Embree only"))
            }
            (true, true) if q == Query::Occluded => None,
            (true, true) => {
                let scale = f64::from(x.t) + f64::from(r.o.abs().max_element());
                let rel = (f64::from(e.t) - f64::from(x.t)).abs() / scale.max(1e-30);
                c.max_rel_t = c.max_rel_t.max(rel);
                if rel > t_tol {
                    c.t_diff += 1;
                    Some(if e.t < x.t {
                        (e.prim as u32, e.t, "ember nearer")
                    } else {
                        (x.prim as u32, x.t, "Embree nearer")
                    })
                } else {
                    c.same_t_other_prim += usize::from(e.prim != x.prim);
                    None
                }
            }
        };
        let Some((mut prim, mut t, what)) = deciding else {
            continue;
        };
        if q == Query::Occluded {
            // Find the blocking triangle: ember's closest hit, or Embree's from INTERSECT.
            let blocker = if eh {
                trace_one(view, Query::Intersect, r)
            } else {
                shadow_hits.map_or(MISS, |s| s[i])
            };
            if blocker.prim < 0 {
                c.other += 1;
                continue;
            }
            (prim, t) = (blocker.prim as u32, blocker.t);
        }
        let (min_bary, cos) = hit_geometry(view, r, prim, t);
        let [p0, p1, p2] = view.triangle_vertices(prim);
        if min_bary.abs() < EDGE_BARY {
            c.edge += 1;
        } else if cos < GRAZING_COS {
            c.grazing += 1;
        } else if what.starts_with("Embree")
            && intersect_triangle(r.o, r.d, f32::INFINITY, p0, p1, p2).is_none()
        {
            c.t_bound += 1;
        } else {
            c.other += 1;
            if c.examples.len() < 5 {
                c.examples.push(format!(
                    "ray {i} ({what}): ember prim {} t {}, Embree prim {} t {}; deciding hit on triangle {prim} at min barycentric {min_bary:.2e}, |cos| {cos:.2e}",
                    e.prim, e.t, x.prim, x.t
                ));
            }
        }
    }
    c
}

// --------------------------------------------------------------------------- main

/// The shape of the wide tree: lanes used per node, primitives and groups per leaf, and the
/// surface-area estimate of what a ray that crosses the root box costs (nodes visited and
/// triangle groups tested, each weighted by its box's area relative to the root's), the
/// figures that a change of the build or the collapse moves before any timing does.
fn tree_shape(data: &SceneData) -> String {
    use ember_kernel::bvh::{WideNode, WIDE_LEAF, WIDTH};
    use ember_kernel::geometry::{Aabb, GROUP_WIDTH};
    let nodes = &data.bvh_nodes;
    let lane_box = |n: &WideNode, l: usize| Aabb {
        min: Vec3::new(n.lo[0][l], n.lo[1][l], n.lo[2][l]),
        max: Vec3::new(n.hi[0][l], n.hi[1][l], n.hi[2][l]),
    };
    let area = |b: Aabb| f64::from(b.surface_area());
    let node_area = |n: &WideNode| {
        area(
            (0..WIDTH)
                .map(|l| lane_box(n, l))
                .fold(Aabb::EMPTY, Aabb::union),
        )
    };
    let Some(root) = nodes.first() else {
        return String::from("empty tree");
    };
    let root_area = node_area(root).max(f64::MIN_POSITIVE);
    let (mut lanes, mut leaves, mut prims, mut groups) = (0usize, 0usize, 0usize, 0usize);
    let (mut sah_nodes, mut sah_groups) = (0.0f64, 0.0f64);
    for n in nodes {
        sah_nodes += node_area(n) / root_area;
        for l in 0..WIDTH {
            let used = n.child[l] & WIDE_LEAF == 0 || n.count[l] > 0;
            lanes += usize::from(used);
            if n.child[l] & WIDE_LEAF != 0 && n.count[l] > 0 {
                let c = usize::from(n.count[l]);
                let g = c.div_ceil(GROUP_WIDTH);
                leaves += 1;
                prims += c;
                groups += g;
                sah_groups += g as f64 * area(lane_box(n, l)) / root_area;
            }
        }
    }
    format!(
        "tree shape: {:.2} of {WIDTH} lanes used per node, {leaves} leaves of {:.2} triangles in {:.2} groups of {GROUP_WIDTH}; surface-area estimate per ray through the root: {sah_nodes:.1} nodes, {sah_groups:.1} groups",
        lanes as f64 / nodes.len() as f64,
        prims as f64 / leaves.max(1) as f64,
        groups as f64 / leaves.max(1) as f64,
    )
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s[s.len() / 2]
}

fn list(v: &[f64]) -> String {
    let items: Vec<String> = v.iter().map(|x| format!("{x:.6}")).collect();
    format!("[{}]", items.join(", "))
}

/// Busy CPU time of the whole machine and of this process, in clock ticks (Linux `/proc`;
/// `None` elsewhere). Their difference over a measurement is what other processes took.
fn cpu_ticks() -> Option<(u64, u64)> {
    let stat = std::fs::read_to_string("/proc/stat").ok()?;
    // cpu  user nice system idle iowait irq softirq steal ...: all but idle and iowait.
    let f: Vec<u64> = stat
        .lines()
        .next()?
        .split_whitespace()
        .skip(1)
        .map(|v| v.parse().unwrap_or(0))
        .collect();
    let machine = f.iter().take(8).sum::<u64>() - f.get(3)? - f.get(4)?;
    let own = std::fs::read_to_string("/proc/self/stat").ok()?;
    // After "(comm)": state is field 3, utime and stime are fields 14 and 15.
    let rest: Vec<&str> = own.rsplit_once(')')?.1.split_whitespace().collect();
    let own = rest.get(11)?.parse::<u64>().ok()? + rest.get(12)?.parse::<u64>().ok()?;
    Some((machine, own))
}

/// Cores' worth of CPU that other processes used between two [`cpu_ticks`] readings `secs`
/// apart (100 ticks per second, Linux's USER_HZ).
fn other_cores(before: Option<(u64, u64)>, after: Option<(u64, u64)>, secs: f64) -> Option<f64> {
    let ((m0, o0), (m1, o1)) = (before?, after?);
    let other = (m1 - m0) as f64 - (o1 - o0) as f64;
    Some((other / 100.0 / secs).max(0.0))
}

/// The 1, 5 and 15-minute load averages (Linux), or "?".
fn loadavg() -> String {
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_else(|_| "?".into());
    load.split_whitespace()
        .take(3)
        .collect::<Vec<_>>()
        .join(" ")
}

fn run(args: &Args) -> Res<()> {
    let mut json = String::new();
    println!(
        "ember-bvh-embree: {} (load average {}); {}-wide BVH nodes ({})",
        args.data.display(),
        loadavg(),
        ember_kernel::bvh::WIDTH,
        if cfg!(target_feature = "avx") {
            "built for AVX"
        } else {
            "built without AVX"
        }
    );
    for scene in &args.scenes {
        let mut data = scene_data(&args.data, scene)?;
        let n_tris = data.triangles.len();
        let mut builds = Vec::new();
        for _ in 0..3 {
            let start = Instant::now();
            data.build_bvh()?;
            builds.push(start.elapsed().as_secs_f64());
        }
        let view = data.view();
        use std::mem::size_of_val;
        let bytes = [
            size_of_val(data.bvh_nodes.as_slice()),
            size_of_val(data.bvh_prim_order.as_slice()),
            size_of_val(data.triangles.as_slice()),
            size_of_val(data.positions.as_slice()),
            size_of_val(data.bvh_leaf_groups.as_slice()),
        ];
        let per_tri = |b: usize| b as f64 / n_tris as f64;
        println!(
            "{scene}: {n_tris} triangles, {} vertices, {} nodes, ray queries in {} lanes; build {:.1} ms (min of 3, median {:.1}); kernel bytes/triangle {:.1} = nodes {:.1} + prim order {:.1} + triangles {:.1} + positions {:.1} + triangle groups {:.1}",
            data.positions.len(),
            data.bvh_nodes.len(),
            ember_cli::simd::in_use(),
            builds.iter().copied().fold(f64::MAX, f64::min) * 1e3,
            median(&builds) * 1e3,
            per_tri(bytes.iter().sum()),
            per_tri(bytes[0]),
            per_tri(bytes[1]),
            per_tri(bytes[2]),
            per_tri(bytes[3]),
            per_tri(bytes[4]),
        );
        println!("{scene}: {}", tree_shape(&data));
        writeln!(
            json,
            "{{\"kind\": \"build\", \"scene\": \"{scene}\", \"simd\": \"{}\", \"bvh_width\": {}, \"triangles\": {n_tris}, \"vertices\": {}, \"nodes\": {}, \"build_s\": {}, \"bytes_nodes\": {}, \"bytes_prim_order\": {}, \"bytes_triangles\": {}, \"bytes_positions\": {}, \"bytes_leaf_groups\": {}}}",
            ember_cli::simd::in_use(),
            ember_kernel::bvh::WIDTH,
            data.positions.len(),
            data.bvh_nodes.len(),
            list(&builds),
            bytes[0],
            bytes[1],
            bytes[2],
            bytes[3],
            bytes[4]
        )
        .expect("string");
        for &(set, q) in &QUERIES {
            let rays = load_rays(&args.data, scene, set)?;
            let mut out = vec![Out::default(); rays.len()];
            for &threads in &args.threads {
                let load_before = loadavg();
                trace(&view, q, &rays, &mut out, threads); // warm-up
                let (ticks, start) = (cpu_ticks(), Instant::now());
                let times: Vec<f64> = (0..args.passes)
                    .map(|_| trace(&view, q, &rays, &mut out, threads))
                    .collect();
                // How much of the machine others took while the timed passes ran.
                let other = other_cores(ticks, cpu_ticks(), start.elapsed().as_secs_f64());
                let other_text = other.map_or("?".to_string(), |c| format!("{c:.2}"));
                let mrays = rays.len() as f64 / median(&times) / 1e6;
                let hits = out.iter().filter(|o| o.prim >= 0).count();
                // Results must not depend on the thread count: compared across runs by hash.
                let hash = results_hash(&out);
                let mut line = format!(
                    "  {set:<10} {:<9} T={threads}: {mrays:7.3} Mrays/s (median of {}; passes {}) hits {hits}, results hash {hash:016x}; other processes {other_text} cores",
                    q.name(),
                    args.passes,
                    times
                        .iter()
                        .map(|t| format!("{:.3}s", t))
                        .collect::<Vec<_>>()
                        .join(" "),
                );
                let mut checks = Vec::new();
                for sub in ["ref", "ref-robust"] {
                    let Some(embree) = load_ref(&args.data, sub, scene, set, q)? else {
                        continue;
                    };
                    if embree.len() != rays.len() {
                        return Err(format!(
                            "results/{sub}: {} results for {} rays",
                            embree.len(),
                            rays.len()
                        ));
                    }
                    let shadow = if q == Query::Occluded {
                        load_ref(&args.data, sub, scene, set, Query::Intersect)?
                    } else {
                        None
                    };
                    let c = check(
                        &view,
                        q,
                        &rays,
                        &out,
                        &embree,
                        shadow.as_deref(),
                        args.t_tol,
                    );
                    write!(line, "\n      vs Embree {sub}: {}", c.summary(rays.len()))
                        .expect("string");
                    for e in &c.examples {
                        write!(line, "\n        {e}").expect("string");
                    }
                    checks.push(format!("\"{sub}\": {}", c.json(rays.len())));
                }
                println!("{line}");
                writeln!(
                    json,
                    "{{\"kind\": \"trace\", \"scene\": \"{scene}\", \"triangles\": {n_tris}, \"rayset\": \"{set}\", \"query\": \"{}\", \"threads\": {threads}, \"rays\": {}, \"times_s\": {}, \"median_s\": {:.6}, \"mrays\": {mrays:.4}, \"hits\": {hits}, \"results_hash\": \"{hash:016x}\", \"other_cores\": {}, \"loadavg_before\": \"{load_before}\", \"loadavg_after\": \"{}\", \"t_tol\": {:e}, \"check\": {{{}}}}}",
                    q.name(),
                    rays.len(),
                    list(&times),
                    median(&times),
                    other.map_or("null".to_string(), |c| format!("{c:.3}")),
                    loadavg(),
                    args.t_tol,
                    checks.join(", ")
                )
                .expect("string");
            }
        }
    }
    if let Some(path) = &args.json {
        std::fs::write(path, json).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok(())
}

/// The host's scene buffers for `scene`, without a BVH yet. intersect/occluded read
/// positions, triangles and the BVH only, so normals, materials and emitters stay empty.
fn scene_data(data: &Path, scene: &str) -> Res<SceneData> {
    let (positions, triangles) = load_scene(data, scene)?;
    Ok(SceneData {
        positions,
        triangles,
        ..SceneData::default()
    })
}

/// `--serve`: one scene's BVH built once, then one timed pass per request line on stdin
/// (`SET QUERY THREADS`), answered on stdout as `SECONDS RESULTS_HASH`; an empty line or end of
/// input ends it. The ray sets are loaded on first use.
fn serve(args: &Args) -> Res<()> {
    use std::io::BufRead as _;
    let scene = &args.scenes[0];
    let mut data = scene_data(&args.data, scene)?;
    data.build_bvh()?;
    let view = data.view();
    let mut sets: Vec<(String, Vec<Ray>)> = Vec::new();
    let mut out = Vec::new();
    println!(
        "ready {scene} {} triangles, ray queries in {} lanes",
        data.triangles.len(),
        ember_cli::simd::in_use()
    );
    for line in std::io::stdin().lock().lines() {
        let line = line.map_err(|e| format!("stdin: {e}"))?;
        let words: Vec<&str> = line.split_whitespace().collect();
        let [set, query, threads] = words[..] else {
            if words.is_empty() {
                break;
            }
            return Err(format!(
                "--serve: expected `SET QUERY THREADS`, got `{line}`"
            ));
        };
        let q = [Query::Intersect, Query::Occluded]
            .into_iter()
            .find(|q| q.name() == query)
            .ok_or(format!("--serve: unknown query `{query}`"))?;
        let threads: usize = threads
            .parse()
            .ok()
            .filter(|&t| t > 0)
            .ok_or(format!("--serve: bad thread count `{threads}`"))?;
        let at = match sets.iter().position(|(name, _)| name == set) {
            Some(at) => at,
            None => {
                sets.push((set.to_string(), load_rays(&args.data, scene, set)?));
                sets.len() - 1
            }
        };
        let rays = &sets[at].1;
        out.resize(rays.len(), Out::default());
        let seconds = trace(&view, q, rays, &mut out, threads);
        println!("{seconds:.9} {:016x}", results_hash(&out));
    }
    Ok(())
}

fn main() {
    if let Err(e) = ember_cli::simd::apply_env()
        .and_then(|()| parse_args())
        .and_then(|a| if a.serve { serve(&a) } else { run(&a) })
    {
        eprintln!("ember-bvh-embree: {e}");
        std::process::exit(1);
    }
}
