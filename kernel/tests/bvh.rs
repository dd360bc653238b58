//! BVH correctness: structure of the built tree, closest-hit and any-hit traversal against
//! brute force, watertightness on closed and open meshes, and the build's error cases; the
//! wide collapse's structure, and its traversal (nearest child first) giving the binary
//! traversal's answers on every query.

use ember_kernel::bvh::closest::{bound_after, precedes};
use ember_kernel::bvh::{
    align_leaves, aligned_order_len, build, collapse, gather_leaf_groups, max_nodes,
    max_wide_nodes, Bvh, BvhError, BvhNode, WideBvh, WideNode, MAX_LEAF_PRIMS, MAX_MERGED_GROUPS,
    NODE_COST, SHORT_TRAVERSAL_STACK, TRAVERSAL_STACK, WIDE_LEAF, WIDE_MAX_DEPTH, WIDTH,
};
use ember_kernel::geometry::{intersect_triangle, Aabb, Ray, TriangleGroup, GROUP_WIDTH};
use ember_kernel::glam::Vec3;
use ember_kernel::math::warp;
use ember_kernel::sampler::{IndependentSampler, Sampler};
use ember_kernel::scene::{Hit, SceneView};
use ember_kernel::simd::Baseline;
use ember_kernel::texture::Textures;
use std::collections::HashMap;

type Tri = [Vec3; 3];

/// Debug builds run fewer rays on the large cases.
const DEBUG: bool = cfg!(debug_assertions);

struct Rng(IndependentSampler);

impl Rng {
    fn new(seed: u64) -> Self {
        Self(IndependentSampler::new(seed, 0, 0))
    }
    fn f(&mut self) -> f32 {
        self.0.next_1d()
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f()
    }
    fn vec(&mut self, lo: f32, hi: f32) -> Vec3 {
        Vec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
    }
    fn dir(&mut self) -> Vec3 {
        let u = self.0.next_2d();
        warp::sample_uniform_sphere(u)
    }
    fn index(&mut self, n: usize) -> usize {
        ((self.f() * n as f32) as usize).min(n - 1)
    }
    /// A uniform point on the triangle.
    fn on_triangle(&mut self, t: &Tri) -> Vec3 {
        let b = warp::sample_uniform_triangle(self.0.next_2d());
        t[0] * (1.0 - b.x - b.y) + t[1] * b.x + t[2] * b.y
    }
}

fn tri_bounds(t: &Tri) -> Aabb {
    Aabb::from_points(t[0], t[1], t[2])
}

struct Built {
    nodes: Vec<BvhNode>,
    prim_order: Vec<u32>,
    wide: Vec<WideNode>,
    /// The wide tree with its leaves aligned to groups (`align_leaves`), its order
    /// and triangle groups, and the soup as a scene's vertex and index buffers: the layout the
    /// renderer traces, through `SceneView`'s lane-wise leaf test.
    grouped: Vec<WideNode>,
    grouped_order: Vec<u32>,
    groups: Vec<TriangleGroup>,
    positions: Vec<Vec3>,
    indices: Vec<[u32; 3]>,
}

impl Built {
    fn new(tris: &[Tri]) -> Self {
        let bounds: Vec<Aabb> = tris.iter().map(tri_bounds).collect();
        let mut nodes = vec![BvhNode::default(); max_nodes(tris.len())];
        let mut prim_order = vec![0u32; tris.len()];
        let used = build(&bounds, &mut nodes, &mut prim_order).expect("build");
        assert!(used >= 1 && used <= max_nodes(tris.len()), "used {used}");
        nodes.truncate(used);
        Self::with_nodes(nodes, prim_order, tris)
    }

    /// Collapses `nodes` to the wide tree as well, and lays that out in groups.
    fn with_nodes(nodes: Vec<BvhNode>, prim_order: Vec<u32>, tris: &[Tri]) -> Self {
        let mut wide = vec![WideNode::default(); max_wide_nodes(nodes.len())];
        let used = collapse(&nodes, &mut wide).expect("collapse");
        wide.truncate(used);
        let mut grouped = wide.clone();
        let mut grouped_order = vec![0u32; aligned_order_len(&wide)];
        let len = align_leaves(&mut grouped, &prim_order, &mut grouped_order).expect("align");
        assert_eq!(len, grouped_order.len());
        let positions: Vec<Vec3> = tris.iter().flatten().copied().collect();
        let indices: Vec<[u32; 3]> = (0..tris.len() as u32)
            .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
            .collect();
        let mut groups = vec![TriangleGroup::default(); len / GROUP_WIDTH];
        gather_leaf_groups(&positions, &indices, &grouped_order, &mut groups).expect("groups");
        Self {
            nodes,
            prim_order,
            wide,
            grouped,
            grouped_order,
            groups,
            positions,
            indices,
        }
    }

    /// The soup as the renderer sees it, traced through the grouped wide tree.
    fn scene(&self) -> SceneView<'_> {
        SceneView {
            positions: &self.positions,
            normals: &self.positions,
            triangles: &self.indices,
            triangle_materials: &[],
            materials: &[],
            emitter_triangles: &[],
            emitter_cdf: &[],
            bvh: WideBvh {
                nodes: &self.grouped,
                prim_order: &self.grouped_order,
                leaf_groups: &self.groups,
            }
            .into(),
            textures: Textures::NONE,
        }
    }

    fn bvh(&self) -> Bvh<'_> {
        Bvh {
            nodes: &self.nodes,
            prim_order: &self.prim_order,
        }
    }

    fn wide_bvh(&self) -> WideBvh<'_> {
        WideBvh {
            nodes: &self.wide,
            prim_order: &self.prim_order,
            leaf_groups: &[],
        }
    }
}

/// Whether the collapse's surface-area rule makes the binary subtree at `i` one leaf
/// (`bvh::collapse`): `groups · A ≤ NODE_COST · A + Σ groups(leaf) · A(leaf)`, computed as the
/// collapse computes it (the leaves summed in pre-order, in f32).
fn merge_pays(b: &Built, ranges: &[(u32, u32)], i: usize) -> bool {
    let (first, end) = ranges[i];
    let groups = ((end - first) as usize).div_ceil(GROUP_WIDTH) as f32;
    let area = b.nodes[i].bounds().surface_area();
    let mut as_node = NODE_COST * area;
    // The subtree's nodes follow it in pre-order up to its last leaf, which ends at `end`.
    for n in &b.nodes[i..] {
        if n.is_leaf() {
            let groups = usize::from(n.count).div_ceil(GROUP_WIDTH) as f32;
            as_node += groups * n.bounds().surface_area();
            if n.offset + u32::from(n.count) == end {
                break;
            }
        }
    }
    groups * area <= as_node
}

/// Checks the wide tree against the binary one it was collapsed from: children after their
/// parent, each wide node reached once, lanes carrying the binary children's exact boxes,
/// leaves covering every primitive slot once, and no deeper than the traversal stack allows.
/// Returns the wide depth.
fn validate_wide(b: &Built) -> usize {
    let (wide, n) = (&b.wide, b.prim_order.len());
    assert!(!wide.is_empty() && wide.len() <= max_wide_nodes(b.nodes.len()));
    // Every binary node as a leaf over its subtree: (first slot, count, box, a binary leaf).
    // Pre-order puts children after their parent, so a reverse pass sees them first.
    let mut ranges = vec![(0u32, 0u32); b.nodes.len()];
    for (i, node) in b.nodes.iter().enumerate().rev() {
        ranges[i] = if node.is_leaf() {
            (node.offset, node.offset + u32::from(node.count))
        } else if i + 1 == b.nodes.len() {
            // The box-less node of an empty scene.
            (0, 0)
        } else {
            (ranges[i + 1].0, ranges[node.offset as usize].1)
        };
    }
    // (first slot, count, lower corner, upper corner, a binary leaf)
    type Subtree = (u32, u16, [f32; 3], [f32; 3], bool);
    let subtrees: Vec<Subtree> = b
        .nodes
        .iter()
        .zip(&ranges)
        .filter(|(n, _)| !(n.is_leaf() && n.count == 0))
        .map(|(n, &(first, end))| (first, (end - first) as u16, n.min, n.max, n.is_leaf()))
        .collect();
    let mut wide_leaves = Vec::new();
    let mut covered = vec![false; n];
    let mut depth = vec![0usize; wide.len()];
    let mut reached = vec![false; wide.len()];
    reached[0] = true;
    depth[0] = 1;
    for (i, node) in wide.iter().enumerate() {
        assert!(reached[i], "wide node {i} unreachable");
        for lane in 0..WIDTH {
            let lo = [0, 1, 2].map(|a| node.lo[a][lane]);
            let hi = [0, 1, 2].map(|a| node.hi[a][lane]);
            if node.is_leaf(lane) {
                let first = node.child[lane] & !WIDE_LEAF;
                let count = node.count[lane];
                if count == 0 {
                    // Unused lane: an empty box.
                    assert!(
                        lo.iter().zip(&hi).all(|(l, h)| l > h),
                        "node {i} lane {lane}"
                    );
                    continue;
                }
                let first = first as usize;
                for (slot, c) in covered[first..first + usize::from(count)]
                    .iter_mut()
                    .enumerate()
                {
                    assert!(!*c, "prim slot {} in two wide leaves", first + slot);
                    *c = true;
                }
                wide_leaves.push((first as u32, count, lo, hi));
            } else {
                let c = node.child[lane] as usize;
                assert!(c > i && c < wide.len(), "node {i} lane {lane}: child {c}");
                assert!(!reached[c], "wide node {c} reached twice");
                reached[c] = true;
                depth[c] = depth[i] + 1;
                // The lane's box is the union of the child's lanes.
                let child = &wide[c];
                for a in 0..3 {
                    let used = (0..WIDTH).filter(|&l| !(child.is_leaf(l) && child.count[l] == 0));
                    let (cl, ch) = used.fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), k| {
                        (l.min(child.lo[a][k]), h.max(child.hi[a][k]))
                    });
                    assert!(lo[a] <= cl && hi[a] >= ch, "node {i} lane {lane} axis {a}");
                }
            }
        }
    }
    assert!(
        covered.iter().all(|&c| c) || n == 0,
        "prims in no wide leaf"
    );
    // Each wide leaf is a binary leaf or a binary subtree of at most `MAX_MERGED_GROUPS`
    // groups, with its box (together with the coverage above: a partition of the slots).
    for &(first, count, lo, hi) in &wide_leaves {
        let source = subtrees
            .iter()
            .find(|s| (s.0, s.1, s.2, s.3) == (first, count, lo, hi));
        let Some(&(.., is_leaf)) = source else {
            panic!("wide leaf {first}+{count} is no binary subtree with the same box");
        };
        assert!(
            is_leaf || usize::from(count).div_ceil(GROUP_WIDTH) <= MAX_MERGED_GROUPS,
            "wide leaf {first}+{count}: a merged subtree over {MAX_MERGED_GROUPS} groups"
        );
        if !is_leaf {
            let i = ranges
                .iter()
                .position(|&r| r == (first, first + u32::from(count)));
            assert!(
                merge_pays(b, &ranges, i.expect("binary subtree")),
                "wide leaf {first}+{count}: merged against the surface-area cost"
            );
        }
    }
    // And a small subtree that the cost says to make one leaf is not a wide node: the slots
    // under each wide node's lanes, bottom up (children come after their parent).
    let mut spans = vec![(u32::MAX, 0u32); wide.len()];
    for (i, node) in wide.iter().enumerate().rev() {
        for lane in 0..WIDTH {
            let (lo, hi) = if node.is_leaf(lane) {
                if node.count[lane] == 0 {
                    continue;
                }
                let first = node.child[lane] & !WIDE_LEAF;
                (first, first + u32::from(node.count[lane]))
            } else {
                spans[node.child[lane] as usize]
            };
            spans[i] = (spans[i].0.min(lo), spans[i].1.max(hi));
        }
    }
    for (i, &span) in spans.iter().enumerate().skip(1) {
        let source = ranges.iter().position(|&r| r == span);
        let source = source.expect("each wide node stands for a binary subtree");
        let groups = ((span.1 - span.0) as usize).div_ceil(GROUP_WIDTH);
        assert!(
            groups > MAX_MERGED_GROUPS || !merge_pays(b, &ranges, source),
            "wide node {i} over slots {span:?} would cost less as one leaf"
        );
    }
    let max = depth.into_iter().max().unwrap_or(1);
    assert!(max <= WIDE_MAX_DEPTH, "wide depth {max} > {WIDE_MAX_DEPTH}");
    max
}

/// Asserts that the wide traversal answers as the binary one: the same closest hit under the
/// closest-hit order ([`bvh_closest`]) and the same any-hit answer, whatever order each visits
/// its children in; returns the number of triangle tests of the wide closest-hit query.
fn assert_same_hits(b: &Built, tris: &[Tri], o: Vec3, d: Vec3, t_max: f32) -> usize {
    bvh_closest(b, tris, o, d, t_max);
    let occluded = b
        .wide_bvh()
        .traverse::<true, _>(o, d, t_max, |_, prim, tmax| {
            let t = &tris[prim as usize];
            intersect_triangle(o, d, tmax, t[0], t[1], t[2]).map(|h| h.t)
        });
    assert_eq!(
        occluded,
        bvh_occluded(b, tris, o, d, t_max),
        "o={o} d={d} t_max={t_max}: any-hit answers differ"
    );
    let mut tests = 0;
    let mut best: Option<(f32, u32)> = None;
    b.wide_bvh()
        .traverse::<false, _>(o, d, t_max, |slot, prim, tmax| {
            tests += 1;
            assert_eq!(b.prim_order[slot as usize], prim, "slot {slot}");
            let t = &tris[prim as usize];
            let h = intersect_triangle(o, d, tmax, t[0], t[1], t[2])?.t;
            if !precedes(h, prim, best) {
                return None;
            }
            best = Some((h, prim));
            Some(bound_after(h))
        });
    tests
}

fn contains(outer: &Aabb, inner: &Aabb) -> bool {
    outer.min.cmple(inner.min).all() && outer.max.cmpge(inner.max).all()
}

/// Checks the layout invariants and returns the depth of the tree (nodes on the longest
/// root-to-leaf path).
fn validate(tris: &[Tri], b: &Built) -> usize {
    validate_with(tris, b, MAX_LEAF_PRIMS)
}

/// [`validate`] allowing leaves of up to `max_leaf` prims with distinct centroids.
fn validate_with(tris: &[Tri], b: &Built, max_leaf: usize) -> usize {
    let n = tris.len();
    let nodes = &b.nodes;
    // prim_order is a permutation of 0..n.
    let mut seen = vec![false; n];
    for &p in &b.prim_order {
        assert!(
            (p as usize) < n && !seen[p as usize],
            "prim_order not a permutation"
        );
        seen[p as usize] = true;
    }
    assert!(nodes.len() <= max_nodes(n));
    if n == 0 {
        assert_eq!(nodes.len(), 1);
        assert!(nodes[0].bounds().is_empty());
        return 1;
    }
    // Depth-first walk: every node reached once, every prim slot covered by exactly one leaf.
    let mut covered = vec![false; n];
    let mut visited = vec![false; nodes.len()];
    // (node, depth); returns subtree size through an explicit stack of pending checks.
    fn subtree(
        i: usize,
        depth: usize,
        max_leaf: usize,
        tris: &[Tri],
        b: &Built,
        covered: &mut [bool],
        visited: &mut [bool],
        max_depth: &mut usize,
    ) -> usize {
        let nodes = &b.nodes;
        assert!(
            i < nodes.len(),
            "child index {i} out of {} nodes",
            nodes.len()
        );
        assert!(!visited[i], "node {i} reached twice");
        visited[i] = true;
        *max_depth = (*max_depth).max(depth);
        let node = nodes[i];
        let bounds = node.bounds();
        if node.is_leaf() {
            let (first, count) = (node.offset as usize, usize::from(node.count));
            assert!(first + count <= b.prim_order.len(), "leaf {i} range");
            let prims = &b.prim_order[first..first + count];
            let c0 = tri_bounds(&tris[prims[0] as usize]).centroid();
            let coincident = prims
                .iter()
                .all(|&p| tri_bounds(&tris[p as usize]).centroid() == c0);
            assert!(
                count <= max_leaf || coincident,
                "leaf {i} holds {count} prims with distinct centroids"
            );
            for (k, &p) in prims.iter().enumerate() {
                assert!(!covered[first + k], "prim slot {} in two leaves", first + k);
                covered[first + k] = true;
                let pb = tri_bounds(&tris[p as usize]);
                assert!(
                    contains(&bounds, &pb),
                    "leaf {i} {bounds:?} misses prim {p} {pb:?}"
                );
            }
            1
        } else {
            assert!(node.axis < 3, "node {i} axis {}", node.axis);
            let second = node.offset as usize;
            assert!(second > i + 1, "node {i}: second child {second}");
            for c in [i + 1, second] {
                assert!(c < nodes.len());
                assert!(
                    contains(&bounds, &nodes[c].bounds()),
                    "node {i} does not contain child {c}"
                );
            }
            let left = subtree(
                i + 1,
                depth + 1,
                max_leaf,
                tris,
                b,
                covered,
                visited,
                max_depth,
            );
            assert_eq!(second, i + 1 + left, "node {i}: not depth-first");
            let right = subtree(
                second,
                depth + 1,
                max_leaf,
                tris,
                b,
                covered,
                visited,
                max_depth,
            );
            1 + left + right
        }
    }
    let mut max_depth = 0;
    let size = subtree(
        0,
        1,
        max_leaf,
        tris,
        b,
        &mut covered,
        &mut visited,
        &mut max_depth,
    );
    assert_eq!(size, nodes.len(), "unreachable nodes");
    assert!(covered.iter().all(|&c| c), "prims in no leaf");
    // The root bounds everything.
    let all = tris.iter().map(tri_bounds).fold(Aabb::EMPTY, Aabb::union);
    assert!(contains(&nodes[0].bounds(), &all));
    max_depth
}

// ---------------------------------------------------------------------------------------------
// Scenes
// ---------------------------------------------------------------------------------------------

fn random_soup(n: usize, seed: u64) -> Vec<Tri> {
    let mut r = Rng::new(seed);
    (0..n)
        .map(|_| {
            let c = r.vec(-1.0, 1.0);
            // Sizes from tiny to a quarter of the scene.
            let s = 0.5 * r.f() * r.f();
            [c + r.vec(-s, s), c + r.vec(-s, s), c + r.vec(-s, s)]
        })
        .collect()
}

/// 200 copies of one triangle, 100 zero-area ones (collinear or a single point), 100 normal.
fn degenerate_soup() -> Vec<Tri> {
    let mut r = Rng::new(77);
    let base = [
        Vec3::new(-0.5, -0.5, 0.1),
        Vec3::new(0.6, -0.4, 0.0),
        Vec3::new(0.0, 0.7, -0.2),
    ];
    let mut v = vec![base; 200];
    for i in 0..100 {
        let a = r.vec(-1.0, 1.0);
        if i % 2 == 0 {
            let b = r.vec(-1.0, 1.0);
            v.push([a, (a + b) * 0.5, b]);
        } else {
            v.push([a, a, a]);
        }
    }
    v.extend(random_soup(100, 78));
    v
}

/// Triangles whose bounding-box centroids are all the same point. Coordinates are multiples
/// of 2⁻¹⁰ so that c ± a and the centroid (min + max)/2 are exact in f32.
fn same_centroid_soup(n: usize) -> Vec<Tri> {
    let mut r = Rng::new(91);
    let q = |v: Vec3| (v * 1024.0).round() / 1024.0;
    let c = Vec3::new(0.25, -0.5, 0.125);
    (0..n)
        .map(|_| {
            let a = q(r.vec(-1.0, 1.0));
            // |b| ≤ |a| per axis, so the bounds are exactly c ± |a|.
            let b = q(a * r.vec(-1.0, 1.0));
            [c + a, c - a, c + b]
        })
        .collect()
}

/// A bumpy height field of `n x n` quads (two triangles each, shared edges), z up.
fn grid(n: usize) -> (Vec<Tri>, Vec<Vec3>) {
    let h = |i: usize, j: usize| {
        let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
        Vec3::new(x, y, 0.1 * (7.0 * x).sin() * (5.0 * y).cos())
    };
    let mut tris = Vec::new();
    let mut verts = Vec::new();
    for i in 0..=n {
        for j in 0..=n {
            verts.push(h(i, j));
        }
    }
    for i in 0..n {
        for j in 0..n {
            let (a, b, c, d) = (h(i, j), h(i + 1, j), h(i + 1, j + 1), h(i, j + 1));
            tris.push([a, b, c]);
            tris.push([a, c, d]);
        }
    }
    (tris, verts)
}

/// Subdivided icosahedron on the unit sphere with shared vertices: `20·4^levels` triangles.
fn icosphere(levels: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut verts: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut faces: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint = |a: u32, b: u32, verts: &mut Vec<Vec3>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                verts.push(((verts[a as usize] + verts[b as usize]) * 0.5).normalize());
                (verts.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(faces.len() * 4);
        for [a, b, c] in faces {
            let ab = midpoint(a, b, &mut verts);
            let bc = midpoint(b, c, &mut verts);
            let ca = midpoint(c, a, &mut verts);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    (verts, faces)
}

// ---------------------------------------------------------------------------------------------
// Queries against brute force
// ---------------------------------------------------------------------------------------------

/// The first of all hits in the closest-hit order (`bvh::closest`: nearer first, the lower
/// triangle index at equal distance).
fn brute_closest(tris: &[Tri], o: Vec3, d: Vec3) -> Option<(u32, f32)> {
    let mut best: Option<(u32, f32)> = None;
    for (i, t) in tris.iter().enumerate() {
        if let Some(h) = intersect_triangle(o, d, f32::INFINITY, t[0], t[1], t[2]) {
            if precedes(h.t, i as u32, best.map(|(p, t)| (t, p))) {
                best = Some((i as u32, h.t));
            }
        }
    }
    best
}

/// The closest hit as the renderer finds it (`SceneView::intersect`'s rule), with the binary
/// tree and with the wide one: both must give the same.
fn bvh_closest(b: &Built, tris: &[Tri], o: Vec3, d: Vec3, t_max: f32) -> Option<(u32, f32)> {
    let search = |wide: bool| {
        let mut best: Option<(u32, f32)> = None;
        let hit = |_: u32, prim: u32, tmax: f32| {
            let t = &tris[prim as usize];
            let h = intersect_triangle(o, d, tmax, t[0], t[1], t[2]).map(|h| h.t)?;
            if !precedes(h, prim, best.map(|(p, t)| (t, p))) {
                return None;
            }
            best = Some((prim, h));
            Some(bound_after(h))
        };
        let any = if wide {
            b.wide_bvh().traverse::<false, _>(o, d, t_max, hit)
        } else {
            b.bvh().traverse::<false, _>(o, d, t_max, hit)
        };
        assert_eq!(any, best.is_some());
        best
    };
    let binary = search(false);
    assert_eq!(
        binary,
        search(true),
        "o={o} d={d}: binary and wide trees differ"
    );
    let mut ray = Ray::new(o, d);
    ray.t_max = t_max;
    let grouped = b.scene().intersect(&ray);
    each_isa(|isa, hit, _| {
        let key = |h: Option<Hit>| h.map(|h| (h.triangle, [h.t, h.b1, h.b2].map(f32::to_bits)));
        assert_eq!(
            key(hit(&b.scene(), &ray)),
            key(grouped),
            "o={o} d={d} t_max={t_max}: the {isa} lanes' closest hit"
        );
    });
    assert_eq!(
        grouped.map(|h| (h.triangle, h.t.to_bits())),
        binary.map(|(p, t)| (p, t.to_bits())),
        "o={o} d={d} t_max={t_max}: the grouped wide tree differs from the binary tree"
    );
    if let (Some(h), Some((p, _))) = (grouped, binary) {
        let t = &tris[p as usize];
        let scalar = intersect_triangle(o, d, t_max, t[0], t[1], t[2]).expect("hit");
        assert_eq!(
            [h.b1, h.b2].map(f32::to_bits),
            [scalar.b1, scalar.b2].map(f32::to_bits),
            "o={o} d={d}: barycentrics of the lane test"
        );
    }
    binary
}

fn bvh_occluded(b: &Built, tris: &[Tri], o: Vec3, d: Vec3, t_max: f32) -> bool {
    let binary = b.bvh().traverse::<true, _>(o, d, t_max, |_, prim, tmax| {
        let t = &tris[prim as usize];
        intersect_triangle(o, d, tmax, t[0], t[1], t[2]).map(|h| h.t)
    });
    let mut ray = Ray::new(o, d);
    ray.t_max = t_max;
    assert_eq!(
        b.scene().occluded(&ray),
        binary,
        "o={o} d={d} t_max={t_max}: any-hit of the grouped wide tree"
    );
    each_isa(|isa, _, occluded| {
        assert_eq!(
            occluded(&b.scene(), &ray),
            binary,
            "o={o} d={d} t_max={t_max}: any-hit of the {isa} lanes"
        );
    });
    binary
}

type ClosestQuery = fn(&SceneView, &Ray) -> Option<Hit>;
type AnyQuery = fn(&SceneView, &Ray) -> bool;

/// Calls `check(name, closest, any)` with the scene's queries in each instruction set this
/// CPU has (`ember_kernel::simd`): the baseline always, AVX2 and AVX-512 (two triangle groups
/// at once) where detected, whichever `SceneView::intersect` picks.
fn each_isa(mut check: impl FnMut(&str, ClosestQuery, AnyQuery)) {
    check(
        "baseline",
        |s, r| s.intersect_in(Baseline, r),
        |s, r| s.occluded_in(Baseline, r),
    );
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    if ember_kernel::simd::Avx::detect().is_some() {
        check(
            "AVX2",
            |s, r| {
                let avx = ember_kernel::simd::Avx::detect().expect("detected above");
                avx.run(|avx| s.intersect_in(avx, r))
            },
            |s, r| {
                let avx = ember_kernel::simd::Avx::detect().expect("detected above");
                avx.run(|avx| s.occluded_in(avx, r))
            },
        );
    }
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    if ember_kernel::simd::Avx512::detect().is_some() {
        check(
            "AVX-512",
            |s, r| {
                let avx = ember_kernel::simd::Avx512::detect().expect("detected above");
                avx.run(|avx| s.intersect_in(avx, r))
            },
            |s, r| {
                let avx = ember_kernel::simd::Avx512::detect().expect("detected above");
                avx.run(|avx| s.occluded_in(avx, r))
            },
        );
    }
}

/// `rays` random rays: origins inside and outside the scene bounds, random directions, a third
/// of them aimed at a random point of a random triangle. Closest hit must match brute force
/// (same t, and the same triangle unless two triangles are hit at the same t); any-hit with a
/// random finite t_max must agree on occlusion.
fn check_queries(tris: &[Tri], b: &Built, rays: usize, seed: u64) {
    let scene = tris.iter().map(tri_bounds).fold(Aabb::EMPTY, Aabb::union);
    let (c, r) = (scene.centroid(), 0.5 * scene.extent().length().max(1e-3));
    let mut rng = Rng::new(seed);
    let (mut hits, mut occluded) = (0, 0);
    for i in 0..rays {
        let o = match i % 3 {
            0 => scene.min + (scene.max - scene.min) * rng.vec(0.0, 1.0),
            _ => c + rng.dir() * (r * rng.range(1.05, 3.0)),
        };
        let d = if i % 3 == 2 && !tris.is_empty() {
            let k = rng.index(tris.len());
            let target = rng.on_triangle(&tris[k]);
            (target - o).normalize_or(Vec3::X)
        } else {
            rng.dir()
        };
        let brute = brute_closest(tris, o, d);
        let fast = bvh_closest(b, tris, o, d, f32::INFINITY);
        assert_same_hits(b, tris, o, d, f32::INFINITY);
        match (brute, fast) {
            (None, None) => {}
            (Some((bp, bt)), Some((fp, ft))) => {
                hits += 1;
                // The same hit exactly: ties are resolved by the order, not by the tree.
                assert_eq!(
                    (fp, ft.to_bits()),
                    (bp, bt.to_bits()),
                    "ray {i} o={o} d={d}: BVH prim {fp} at {ft} vs brute prim {bp} at {bt}"
                );
            }
            _ => panic!("ray {i} o={o} d={d}: brute {brute:?} vs BVH {fast:?}"),
        }
        // Any hit with a finite t_max.
        let t_max = rng.range(0.0, 2.0 * r);
        let brute_occ = tris
            .iter()
            .filter_map(|t| intersect_triangle(o, d, t_max, t[0], t[1], t[2]))
            .map(|h| h.t)
            .fold(None, |m: Option<f32>, t| Some(m.map_or(t, |m| m.min(t))));
        let fast_occ = bvh_occluded(b, tris, o, d, t_max);
        assert_same_hits(b, tris, o, d, t_max);
        if brute_occ.is_some() != fast_occ {
            // Only a hit within rounding of t_max may be seen by one and not the other.
            let near = brute_occ.is_some_and(|t| (t - t_max).abs() <= 1e-5 * t_max);
            assert!(
                near,
                "ray {i} o={o} d={d} t_max={t_max}: brute {brute_occ:?} vs BVH {fast_occ}"
            );
        }
        occluded += usize::from(fast_occ);
        // The closest hit must also be found with t_max just above it.
        if let Some((_, bt)) = brute {
            let again = bvh_closest(b, tris, o, d, bt * 1.0001);
            assert!(
                again.is_some(),
                "ray {i}: lost hit at t = {bt} with t_max above it"
            );
        }
    }
    // The test must exercise both outcomes.
    if tris.len() >= 7 {
        assert!(hits > rays / 10 && hits < rays, "{hits} hits of {rays}");
        assert!(occluded > 0, "no occluded rays");
    }
}

fn check_soup(tris: &[Tri], rays: usize, seed: u64) -> usize {
    let b = Built::new(tris);
    let depth = validate(tris, &b);
    assert!(
        depth <= TRAVERSAL_STACK,
        "tree depth {depth} exceeds the traversal stack"
    );
    validate_wide(&b);
    check_queries(tris, &b, rays, seed);
    depth
}

// ---------------------------------------------------------------------------------------------
// Tests
// ---------------------------------------------------------------------------------------------

#[test]
fn random_soups_build_valid_trees_and_match_brute_force() {
    for (k, &n) in [1usize, 2, 7, 100, 5000].iter().enumerate() {
        let tris = random_soup(n, 10 + k as u64);
        let rays = if n >= 5000 && DEBUG { 2_000 } else { 10_000 };
        check_soup(&tris, rays, 20 + k as u64);
    }
}

#[test]
fn degenerate_and_coincident_triangles() {
    let tris = degenerate_soup();
    check_soup(&tris, 10_000, 31);
    // Only copies of one triangle: every centroid coincides, and every hit is a 300-way tie
    // that the order resolves to the first copy, whatever the trees' leaf order.
    let base = degenerate_soup()[0];
    let copies = vec![base; 300];
    check_soup(&copies, 2_000, 32);
    let b = Built::new(&copies);
    assert_ne!(
        b.bvh().prim_order[0],
        0,
        "the tree should not list copy 0 first"
    );
    let mut rng = Rng::new(34);
    let mut ties = 0;
    for _ in 0..500 {
        let target = rng.on_triangle(&base);
        let o = target + rng.dir() * 2.0;
        if let Some((prim, _)) =
            bvh_closest(&b, &copies, o, (target - o).normalize(), f32::INFINITY)
        {
            assert_eq!(prim, 0);
            ties += 1;
        }
    }
    assert!(ties > 400, "{ties} rays hit the copies");
    // Only zero-area triangles: nothing can be hit.
    let flat: Vec<Tri> = degenerate_soup()[200..300].to_vec();
    let b = Built::new(&flat);
    validate(&flat, &b);
    let mut rng = Rng::new(33);
    for _ in 0..2_000 {
        let (o, d) = (rng.vec(-2.0, 2.0), rng.dir());
        assert_eq!(bvh_closest(&b, &flat, o, d, f32::INFINITY), None);
        assert_eq!(brute_closest(&flat, o, d), None);
    }
}

#[test]
fn triangles_with_one_centroid() {
    let tris = same_centroid_soup(500);
    let c0 = tri_bounds(&tris[0]).centroid();
    assert!(tris.iter().all(|t| tri_bounds(t).centroid() == c0));
    check_soup(&tris, 10_000, 41);
}

#[test]
fn grid_with_shared_edges_is_watertight_from_above() {
    let n = if DEBUG { 30 } else { 60 };
    let (tris, verts) = grid(n);
    check_soup(&tris, 10_000, 51);
    let b = Built::new(&tris);
    // Vertical rays through every vertex and edge midpoint of the interior, and random points:
    // the height field covers (0, 1)², so every one of them must hit.
    let mut targets: Vec<(f32, f32)> = Vec::new();
    for v in &verts {
        if v.x > 0.0 && v.x < 1.0 && v.y > 0.0 && v.y < 1.0 {
            targets.push((v.x, v.y));
        }
    }
    for i in 1..n {
        for j in 0..n {
            let (a, c) = (i as f32 / n as f32, (j as f32 + 0.5) / n as f32);
            targets.extend([(a, c), (c, a), (c, c)]);
        }
    }
    let mut rng = Rng::new(52);
    for _ in 0..20_000 {
        targets.push((rng.range(0.01, 0.99), rng.range(0.01, 0.99)));
    }
    // Not exactly vertical: a ray with d.x = 0 whose o.x lies on a box face is lost by the
    // slab test (see `axis_parallel_rays_on_box_faces_are_not_lost`).
    let mut leaks = Vec::new();
    for &(x, y) in &targets {
        for d in [
            Vec3::new(0.013, -0.007, -1.0).normalize(),
            Vec3::new(-1e-4, 2e-4, -1.0).normalize(),
        ] {
            let o = Vec3::new(x, y, 0.0) - d * 2.0;
            if bvh_closest(&b, &tris, o, d, f32::INFINITY).is_none() {
                leaks.push((x, y, d));
            }
        }
    }
    assert!(
        leaks.is_empty(),
        "{} leaks, e.g. {:?}",
        leaks.len(),
        &leaks[..leaks.len().min(5)]
    );
}

#[test]
fn closed_icosphere_has_no_leaks() {
    let (verts, faces) = icosphere(4);
    assert_eq!(faces.len(), 5120);
    let tris: Vec<Tri> = faces.iter().map(|f| f.map(|i| verts[i as usize])).collect();
    let b = Built::new(&tris);
    let depth = validate(&tris, &b);
    assert!(depth <= TRAVERSAL_STACK);
    let rays = if DEBUG { 30_000 } else { 100_000 };
    let mut rng = Rng::new(61);
    let mut leaks = Vec::new();
    let shoot = |o: Vec3, d: Vec3, leaks: &mut Vec<(Vec3, Vec3)>| {
        match bvh_closest(&b, &tris, o, d, f32::INFINITY) {
            Some((_, t)) => {
                // A hit from inside a convex mesh inscribed in the unit sphere.
                let r = (o + d * t).length();
                assert!(
                    t > 0.0 && r <= 1.0 + 1e-5 && r > 0.99,
                    "o={o} d={d} t={t} r={r}"
                );
            }
            None => leaks.push((o, d)),
        }
        assert!(bvh_occluded(&b, &tris, o, d, 10.0) || leaks.last() == Some(&(o, d)));
    };
    for i in 0..rays {
        let o = if i % 2 == 0 {
            // Near the centre.
            rng.dir() * rng.range(0.0, 0.01)
        } else {
            // Just inside the surface: a surface point pulled 0.1% towards the centre (the
            // mesh is convex and contains the centre, so this is inside).
            let k = rng.index(tris.len());
            rng.on_triangle(&tris[k]) * 0.999
        };
        shoot(o, rng.dir(), &mut leaks);
    }
    // The hard cases: rays straight through vertices and along shared edges.
    // (From random origins: rays from the exact centre along directions with a zero
    // component are the slab-test bug of `axis_parallel_rays_on_box_faces_are_not_lost`.)
    for (k, v) in verts.iter().enumerate() {
        let o = rng.dir() * 0.3;
        shoot(o, (*v - o).normalize(), &mut leaks);
        if k % 4 == 0 {
            shoot(*v * 0.999, rng.dir(), &mut leaks);
        }
    }
    for f in &faces {
        for e in 0..3 {
            let (a, c) = (verts[f[e] as usize], verts[f[(e + 1) % 3] as usize]);
            for s in [0.5, rng.f()] {
                let p = a + (c - a) * s;
                let o = rng.dir() * 0.5;
                shoot(o, (p - o).normalize(), &mut leaks);
            }
        }
    }
    assert!(
        leaks.is_empty(),
        "{} leaks, e.g. {:?}",
        leaks.len(),
        &leaks[..leaks.len().min(5)]
    );
}

/// Regression test for a kernel bug (kernel/src/geometry/aabb.rs, `Aabb::hit`): when a direction component is 0
/// and the origin lies exactly on that axis' slab plane, `(min - o) * inv_d` is `0 * inf =
/// NaN`; the NaN then survives the `if ty0 > t0 { t0 = ty0 }` updates and the final
/// `t0 < t_max` is false, so the box is reported as missed. Every subtree whose box has a face
/// on the ray is skipped. A small case: a strip of 16 triangles over x ∈ [−4, 4], ray
/// o = (0, 0.25, 1), d = (0, 0, −1) down the shared edge x = 0: `intersect_triangle`
/// (watertight) hits one of the two triangles there, the BVH finds nothing. Realistic cases: the exact centre of an icosphere shooting along ±z, or
/// towards a vertex with a zero coordinate; vertical rays through the vertices of a grid.
/// Fix: update with NaN-ignoring `t0 = t0.max(ty0)`, `t1 = t1.min(ty1)` (IEEE maxNum).
///
/// (A kernel bug this test found, fixed in `Aabb::hit`.)
#[test]
fn axis_parallel_rays_on_box_faces_are_not_lost() {
    let mut leaks: Vec<String> = Vec::new();
    let mut check = |name: &str, tris: &[Tri], b: &Built, o: Vec3, d: Vec3| {
        let brute = brute_closest(tris, o, d);
        assert!(
            brute.is_some(),
            "{name}: the intersector itself leaks at o={o} d={d}"
        );
        if bvh_closest(b, tris, o, d, f32::INFINITY).is_none() {
            leaks.push(format!("{name} o={o} d={d}"));
        }
        // Origins on box planes with zero direction components: the wide slab test's NaN
        // handling must decide as the scalar one.
        assert_same_hits(b, tris, o, d, f32::INFINITY);
    };
    // A strip of unit quads along x ∈ [−4, 4]; the ray runs down the shared edge x = 0.
    let strip: Vec<Tri> = (-4..4)
        .flat_map(|i| {
            let x = i as f32;
            let (a, b) = (Vec3::new(x, 0.0, 0.0), Vec3::new(x + 1.0, 0.0, 0.0));
            let (c, d) = (Vec3::new(x + 1.0, 1.0, 0.0), Vec3::new(x, 1.0, 0.0));
            [[a, b, c], [a, c, d]]
        })
        .collect();
    let b = Built::new(&strip);
    check(
        "strip edge",
        &strip,
        &b,
        Vec3::new(0.0, 0.25, 1.0),
        Vec3::NEG_Z,
    );
    let (verts, faces) = icosphere(4);
    let sphere: Vec<Tri> = faces.iter().map(|f| f.map(|i| verts[i as usize])).collect();
    let b = Built::new(&sphere);
    for d in [
        Vec3::X,
        Vec3::NEG_X,
        Vec3::Y,
        Vec3::NEG_Y,
        Vec3::Z,
        Vec3::NEG_Z,
    ] {
        check("icosphere centre", &sphere, &b, Vec3::ZERO, d);
    }
    for v in &verts[..12] {
        check("icosphere centre to vertex", &sphere, &b, Vec3::ZERO, *v);
    }
    let (grid_tris, grid_verts) = grid(10);
    let b = Built::new(&grid_tris);
    for v in &grid_verts {
        if v.x > 0.0 && v.x < 1.0 && v.y > 0.0 && v.y < 1.0 {
            check(
                "grid vertex",
                &grid_tris,
                &b,
                Vec3::new(v.x, v.y, 2.0),
                Vec3::NEG_Z,
            );
        }
    }
    assert!(
        leaks.is_empty(),
        "BVH leaks {} rays the intersector hits: {:?}",
        leaks.len(),
        &leaks[..leaks.len().min(4)]
    );
}

/// 93 small triangles at −16^e along x, y and z (e = 15 … −15). At every level the binned SAH
/// can only separate the outermost triangle (all others fall into the last of the 16 bins), so
/// the tree is a chain of depth 90 with the rest of the scene always in the second (upper)
/// child. A ray with a negative direction visits the upper child first and pushes the peeled
/// leaf, one stack entry per level.
fn deep_chain() -> Vec<Tri> {
    let mut tris = Vec::new();
    for e in (-15..=15).rev() {
        let m = 16f32.powi(e);
        for axis in 0..3 {
            let mut c = Vec3::ZERO;
            c[axis] = -m;
            let (u, v) = (Vec3::AXES[(axis + 1) % 3], Vec3::AXES[(axis + 2) % 3]);
            tris.push([c - u - v, c + u - v, c + v]);
        }
    }
    tris
}

/// Regression test for a kernel bug (kernel/src/bvh/traverse.rs, `TRAVERSAL_STACK` and `Bvh::traverse`, the
/// `stack[sp] = far as u32` line): the doc comment says the build never produces a tree deeper
/// than `BUILD_STACK`, but `BUILD_STACK` in kernel/src/bvh/build.rs only bounds the number of
/// *pending right-hand tasks* (`sp`), not the depth: a split whose large side is the second
/// child pops straight back to sp = 1, so a chain of such splits is unbounded in depth. With
/// [`deep_chain`] the build succeeds with depth 90, and traversing
/// o = (0.5, 0.5, 0.5), d = −(1, 1, 1)/√3 panics with "index out of bounds: the len is 65 but
/// the index is 65". Fix: carry the depth in `Task` and stop splitting by SAH (object median
/// or leaf) before it reaches `TRAVERSAL_STACK`, or check `sp` in the traversal.
///
/// (A kernel bug this test found, fixed by the depth limit of the build.)
#[test]
fn deep_unbalanced_tree_fits_the_traversal_stack() {
    let tris = deep_chain();
    let b = Built::new(&tris);
    // A depth-limited build may end in a large leaf.
    let depth = validate_with(&tris, &b, tris.len());
    let wide_depth = validate_wide(&b);
    // Each wide level spans at least two binary levels.
    assert!(
        wide_depth <= depth.div_ceil(2),
        "wide {wide_depth} for binary {depth}"
    );
    let (o, d) = (Vec3::splat(0.5), Vec3::splat(-1.0).normalize());
    assert!(assert_same_hits(&b, &tris, o, d, f32::INFINITY) > 0);
    let brute = brute_closest(&tris, o, d);
    assert!(brute.is_some());
    let fast = bvh_closest(&b, &tris, o, d, f32::INFINITY);
    assert_eq!(fast.map(|h| h.1), brute.map(|h| h.1));
    assert!(
        depth <= TRAVERSAL_STACK,
        "depth {depth} > {TRAVERSAL_STACK}"
    );
    // Rays towards every triangle from around the origin, where the chain nests.
    let mut rng = Rng::new(71);
    for t in &tris {
        let o = rng.vec(-2.0, 2.0);
        let d = (rng.on_triangle(t) - o).normalize();
        let brute = brute_closest(&tris, o, d).map(|h| h.1);
        let fast = bvh_closest(&b, &tris, o, d, f32::INFINITY).map(|h| h.1);
        assert_eq!(fast, brute, "o={o} d={d}");
        assert_same_hits(&b, &tris, o, d, f32::INFINITY);
    }
}

/// A tree made by hand in which a ray along +x enters every box and meets the nearest
/// triangles deepest: a chain whose every node holds the farthest remaining triangle as a leaf
/// beside the subtree of the nearer ones. Its wide collapse has three leaves and one interior
/// child per node, 16 levels; at each the walk descends first and defers the three leaves, so
/// it outgrows the short stack (`SHORT_TRAVERSAL_STACK`) and is made again with the full one.
/// Hits, any-hit answers and the flags returned must be those of brute force and the binary
/// tree, in both directions and with bounds before, inside and after the triangles.
#[test]
fn walks_that_outgrow_the_short_stack_are_made_again() {
    let n = 48usize;
    // Triangle k across the x axis at x = n − k.
    let tris: Vec<Tri> = (0..n)
        .map(|k| {
            let x = (n - k) as f32;
            [
                Vec3::new(x, -1.0, -1.0),
                Vec3::new(x, 3.0, -1.0),
                Vec3::new(x, -1.0, 3.0),
            ]
        })
        .collect();
    let bounds_of = |ks: std::ops::Range<usize>| {
        ks.map(|k| tri_bounds(&tris[k]))
            .fold(Aabb::EMPTY, Aabb::union)
    };
    let node = |b: Aabb, offset: usize, count: u16| BvhNode {
        min: b.min.to_array(),
        offset: offset as u32,
        max: b.max.to_array(),
        count,
        axis: 0,
        pad: 0,
    };
    // Pre-order: interior k over triangles k.., then its leaf (triangle k), then the rest.
    let mut nodes = Vec::new();
    for k in 0..n - 1 {
        let i = nodes.len();
        nodes.push(node(bounds_of(k..n), i + 2, 0));
        nodes.push(node(bounds_of(k..k + 1), k, 1));
    }
    nodes.push(node(bounds_of(n - 1..n), n - 1, 1));
    let b = Built::with_nodes(nodes, (0..n as u32).collect(), &tris);
    validate_wide(&b);
    // A ray along the chain enters every box; each node defers all but one of its children,
    // more in all than the short stack holds (the collapse makes the nearest 24 or so
    // triangles one leaf, `bvh::NODE_COST`, and the chain above stays deep enough).
    let deferred: usize = b
        .wide
        .iter()
        .map(|n| {
            (0..WIDTH)
                .filter(|&l| !(n.is_leaf(l) && n.count[l] == 0))
                .count()
                - 1
        })
        .sum();
    assert!(deferred > SHORT_TRAVERSAL_STACK, "{deferred} deferred");
    for (o, d) in [
        (Vec3::new(0.0, 0.0, 0.0), Vec3::X),
        (
            Vec3::new(0.0, 0.1, 0.2),
            Vec3::new(1.0, 0.01, 0.02).normalize(),
        ),
        (Vec3::new(n as f32 + 1.0, 0.0, 0.0), Vec3::NEG_X),
    ] {
        let brute = brute_closest(&tris, o, d);
        assert!(brute.is_some(), "o={o} d={d}: the ray misses the triangles");
        for t_max in [f32::INFINITY, 0.5, 10.5, n as f32 + 2.0] {
            let fast = bvh_closest(&b, &tris, o, d, t_max);
            let expected = brute.filter(|&(_, t)| t < t_max);
            assert_eq!(
                fast.map(|(p, t)| (p, t.to_bits())),
                expected.map(|(p, t)| (p, t.to_bits())),
                "o={o} d={d} t_max={t_max}"
            );
            assert_same_hits(&b, &tris, o, d, t_max);
            assert_eq!(bvh_occluded(&b, &tris, o, d, t_max), expected.is_some());
        }
    }
}

/// A binary tree made by hand for the collapse's merge rule.
enum Shape {
    /// Triangles `first..first + count`.
    Leaf(usize, usize),
    Node(Box<Shape>, Box<Shape>),
}

/// Appends `shape`'s nodes in pre-order (the build's layout) and returns their box.
fn emit(shape: &Shape, tris: &[Tri], nodes: &mut Vec<BvhNode>) -> Aabb {
    let at = nodes.len();
    nodes.push(BvhNode::default());
    let (bounds, offset, count) = match shape {
        Shape::Leaf(first, count) => {
            let b = tris[*first..first + count]
                .iter()
                .map(tri_bounds)
                .fold(Aabb::EMPTY, Aabb::union);
            (b, *first, *count)
        }
        Shape::Node(left, right) => {
            let l = emit(left, tris, nodes);
            let second = nodes.len();
            (l.union(emit(right, tris, nodes)), second, 0)
        }
    };
    nodes[at] = BvhNode {
        min: bounds.min.to_array(),
        offset: offset as u32,
        max: bounds.max.to_array(),
        count: count as u16,
        axis: 0,
        pad: 0,
    };
    bounds
}

/// The collapse's choice between a small subtree as a node and as one leaf. `WIDTH − 1`
/// clusters of one group each, far apart on the x axis, in a chain (each interior node holds
/// one cluster beside the rest), end in a last subtree `tail` near the end of the chain: the
/// collapse opens the chain, the largest boxes first, until the root's lanes hold the
/// clusters and `tail`, which is then one leaf or a node of its own:
/// - two far-apart clusters: two group tests as a leaf, against `NODE_COST` (two) plus next
///   to nothing for the tiny clusters as a node: one leaf of two groups;
/// - three: three tests against two and next to nothing: a node;
/// - two leaves of `MAX_MERGED_GROUPS` groups each in one spot: a leaf would cost less
///   (`16·A` against `(2 + 16)·A`) but is larger than any leaf the collapse makes: a node.
#[test]
fn small_subtrees_become_leaves_where_the_surface_area_cost_says() {
    assert_eq!(
        NODE_COST, 2.0,
        "the cases below are set for a node cost of two groups"
    );
    let g = GROUP_WIDTH;
    // `count` tiny triangles at x, stacked in z.
    let cluster = |x: f32, count: usize| -> Vec<Tri> {
        (0..count)
            .map(|k| {
                let z = k as f32 * 1e-4;
                [
                    Vec3::new(x, 0.0, z),
                    Vec3::new(x + 1e-3, 0.0, z),
                    Vec3::new(x, 1e-3, z),
                ]
            })
            .collect()
    };
    let big = MAX_MERGED_GROUPS * g;
    let chain = WIDTH - 1;
    // (the tail's clusters as (x, triangles), the root's leaves of several groups as
    // (first slot, count), wide nodes)
    type Case<'a> = (&'a [(f32, usize)], Vec<(u32, u16)>, usize);
    let tails: [Case; 3] = [
        (
            &[(700.0, g), (710.0, g)],
            vec![((chain * g) as u32, 2 * g as u16)],
            1,
        ),
        (&[(700.0, g), (710.0, g), (720.0, g)], vec![], 2),
        (&[(700.0, big), (700.0, big)], vec![], 2),
    ];
    for (tail, merged, wide_nodes) in tails {
        let mut tris: Vec<Tri> = (0..chain)
            .flat_map(|k| cluster(100.0 * k as f32, g))
            .collect();
        // The tail: a chain over its clusters too.
        let mut shape: Option<Shape> = None;
        let mut firsts = Vec::new();
        for &(x, count) in tail {
            firsts.push((tris.len(), count));
            tris.extend(cluster(x, count));
        }
        for &(first, count) in firsts.iter().rev() {
            let leaf = Shape::Leaf(first, count);
            shape = Some(match shape {
                None => leaf,
                Some(rest) => Shape::Node(Box::new(leaf), Box::new(rest)),
            });
        }
        for k in (0..chain).rev() {
            let rest = shape.take().expect("tail");
            shape = Some(Shape::Node(Box::new(Shape::Leaf(k * g, g)), Box::new(rest)));
        }
        let mut nodes = Vec::new();
        emit(&shape.expect("tree"), &tris, &mut nodes);
        let b = Built::with_nodes(nodes, (0..tris.len() as u32).collect(), &tris);
        validate_wide(&b);
        assert_eq!(b.wide.len(), wide_nodes, "tail {tail:?}");
        let root = &b.wide[0];
        let multi: Vec<(u32, u16)> = (0..WIDTH)
            .filter(|&l| root.is_leaf(l) && usize::from(root.count[l]) > g)
            .map(|l| (root.child[l] & !WIDE_LEAF, root.count[l]))
            .collect();
        assert_eq!(multi, merged, "tail {tail:?}");
        let o = Vec3::new(-1.0, 5e-4, 2e-4);
        for &(x, _) in tail {
            let d = (Vec3::new(x + 2e-4, 2e-4, 0.0) - o).normalize();
            assert_same_hits(&b, &tris, o, d, f32::INFINITY);
        }
    }
}

/// The collapse of the smallest trees, its refusals of bad input, and the wide traversal on
/// degenerate rays (zero direction components, origins on box planes, NaN) against binary.
#[test]
fn wide_collapse_edge_cases() {
    // Empty scene: a root with no lanes; nothing is called.
    let empty = Built::new(&[]);
    assert_eq!(empty.wide.len(), 1);
    validate_wide(&empty);
    assert!(!empty.wide_bvh().traverse::<false, _>(
        Vec3::ZERO,
        Vec3::X,
        f32::INFINITY,
        |_, _, _| panic!("called")
    ));
    let nan = Vec3::splat(f32::NAN);
    assert!(!empty
        .wide_bvh()
        .traverse::<false, _>(nan, nan, f32::INFINITY, |_, _, _| panic!("called")));
    // One leaf, two leaves, and a small soup: same answers as binary.
    let soup = random_soup(40, 5);
    for n in [1, 2, 3, 5, 40] {
        let tris = &soup[..n];
        let b = Built::new(tris);
        validate_wide(&b);
        let mut rng = Rng::new(n as u64);
        let mut total = 0;
        for _ in 0..200 {
            let o = rng.vec(-1.5, 1.5);
            let t = &tris[rng.index(n)];
            let d = (rng.on_triangle(t) - o).normalize_or(Vec3::X);
            total += assert_same_hits(&b, tris, o, d, f32::INFINITY);
        }
        assert!(total >= 200, "{n} triangles: only {total} calls");
    }
    // A box of axis-aligned quads: rays along the axes from points on the faces and edges,
    // with signed zero directions.
    let (verts, faces) = icosphere(1);
    let sphere: Vec<Tri> = faces.iter().map(|f| f.map(|i| verts[i as usize])).collect();
    let b = Built::new(&sphere);
    let bounds = sphere.iter().map(tri_bounds).fold(Aabb::EMPTY, Aabb::union);
    for o in [
        Vec3::ZERO,
        bounds.min,
        bounds.max,
        Vec3::new(bounds.min.x, 0.0, 0.0),
        Vec3::new(0.0, bounds.max.y, 0.0),
        b.nodes[1].bounds().min,
        b.nodes[1].bounds().max,
    ] {
        for d in [
            Vec3::X,
            Vec3::NEG_X,
            Vec3::new(0.0, -0.0, 1.0),
            Vec3::new(-0.0, 1.0, -0.0),
            Vec3::new(1.0, 1.0, 0.0).normalize(),
            Vec3::new(-0.0, -1.0, -1.0).normalize(),
            nan,
        ] {
            assert_same_hits(&b, &sphere, o, d, f32::INFINITY);
            assert_same_hits(&b, &sphere, o, d, 0.5);
        }
    }
    // Refusals: too little room, children that do not follow their parent.
    let b = Built::new(&soup);
    let needed = max_wide_nodes(b.nodes.len());
    let mut small = vec![WideNode::default(); needed - 1];
    assert_eq!(
        collapse(&b.nodes, &mut small),
        Err(BvhError::NodeCapacity {
            needed,
            given: needed - 1
        })
    );
    let mut out = vec![WideNode::default(); needed];
    let mut backwards = b.nodes.clone();
    let interior = backwards.iter().position(|n| !n.is_leaf()).unwrap();
    backwards[interior].offset = 0;
    assert_eq!(collapse(&backwards, &mut out), Err(BvhError::Malformed));
    // A hand-made chain far deeper than the build makes: each interior node has a leaf as its
    // first child. The collapse refuses it rather than make a tree the traversal stack cannot
    // hold; a chain within the limit collapses.
    let chain = |interior: u32| -> Vec<BvhNode> {
        let mut nodes = Vec::new();
        for k in 0..interior {
            let i = nodes.len() as u32;
            nodes.push(BvhNode {
                offset: i + 2,
                ..BvhNode::default()
            });
            nodes.push(BvhNode {
                offset: k,
                count: 1,
                ..BvhNode::default()
            });
        }
        nodes.push(BvhNode {
            offset: interior,
            count: 1,
            ..BvhNode::default()
        });
        nodes
    };
    // (A chain of n collapses to about n / (WIDTH − 1) wide levels.)
    let deep = chain((WIDE_MAX_DEPTH * WIDTH) as u32);
    let mut out = vec![WideNode::default(); max_wide_nodes(deep.len())];
    assert_eq!(collapse(&deep, &mut out), Err(BvhError::TooDeep));
    let shallow = chain(100);
    let mut out = vec![WideNode::default(); max_wide_nodes(shallow.len())];
    let used = collapse(&shallow, &mut out).unwrap();
    assert!(
        used <= WIDE_MAX_DEPTH,
        "{used} wide nodes for a chain of 100"
    );
    let mut truncated = b.nodes.clone();
    truncated.truncate(3);
    assert_eq!(
        collapse(&truncated, &mut vec![WideNode::default(); 8]),
        Err(BvhError::Malformed)
    );
}

#[test]
fn build_errors_and_empty_scene() {
    let tris = random_soup(10, 1);
    let bounds: Vec<Aabb> = tris.iter().map(tri_bounds).collect();
    let mut nodes = vec![BvhNode::default(); max_nodes(10) - 1];
    let mut prims = vec![0u32; 10];
    assert_eq!(
        build(&bounds, &mut nodes, &mut prims),
        Err(BvhError::NodeCapacity {
            needed: 19,
            given: 18
        })
    );
    let mut nodes = vec![BvhNode::default(); max_nodes(10)];
    for len in [9, 11, 0] {
        let mut prims = vec![0u32; len];
        assert_eq!(
            build(&bounds, &mut nodes, &mut prims),
            Err(BvhError::PrimOrderLength {
                needed: 10,
                given: len
            })
        );
    }
    // Extra capacity is fine and left untouched.
    let mut nodes = vec![BvhNode::default(); 40];
    nodes[39].pad = 7;
    let mut prims = vec![0u32; 10];
    let used = build(&bounds, &mut nodes, &mut prims).unwrap();
    assert!(used <= 19);
    assert_eq!(nodes[39].pad, 7);
    // No primitives: one empty node that nothing hits; an empty node slice hits nothing.
    assert_eq!(max_nodes(0), 1);
    let mut nodes = vec![BvhNode::default(); 1];
    assert_eq!(build(&[], &mut nodes, &mut []), Ok(1));
    assert!(nodes[0].bounds().is_empty());
    let empty = Built::with_nodes(nodes, Vec::new(), &[]);
    validate(&[], &empty);
    let mut called = false;
    assert!(!empty
        .bvh()
        .traverse::<false, _>(Vec3::ZERO, Vec3::X, f32::INFINITY, |_, _, _| {
            called = true;
            Some(0.0)
        }));
    assert!(!called);
    let none = Bvh {
        nodes: &[],
        prim_order: &[],
    };
    assert!(!none.traverse::<true, _>(Vec3::ZERO, Vec3::X, 1.0, |_, _, _| Some(0.0)));
    assert!(BvhError::TooDeep
        .to_string()
        .contains(&ember_kernel::bvh::MAX_DEPTH.to_string()));
}

/// `align_leaves` starts every leaf at a group boundary with the leaf's own triangles in the
/// same order, pads with its last one, and refuses short buffers and leaves beyond the order;
/// `gather_leaf_groups` holds each slot's triangle and refuses a wrong group count.
#[test]
fn leaves_aligned_to_groups_keep_their_triangles() {
    let tris = random_soup(3000, 11);
    let b = Built::new(&tris);
    let (mut leaves, mut multi_group) = (0, 0);
    for (w, g) in b.wide.iter().zip(&b.grouped) {
        for lane in 0..WIDTH {
            assert_eq!(w.count[lane], g.count[lane]);
            assert_eq!(w.is_leaf(lane), g.is_leaf(lane));
            if !w.is_leaf(lane) {
                assert_eq!(w.child[lane], g.child[lane]);
                continue;
            }
            let count = usize::from(w.count[lane]);
            if count == 0 {
                continue;
            }
            leaves += 1;
            multi_group += usize::from(count > GROUP_WIDTH);
            let (a, z) = (
                (w.child[lane] & !WIDE_LEAF) as usize,
                (g.child[lane] & !WIDE_LEAF) as usize,
            );
            assert_eq!(z % GROUP_WIDTH, 0, "leaf at {z}");
            assert_eq!(b.prim_order[a..a + count], b.grouped_order[z..z + count]);
            let padded = count.div_ceil(GROUP_WIDTH) * GROUP_WIDTH;
            assert!(b.grouped_order[z + count..z + padded]
                .iter()
                .all(|&p| p == b.prim_order[a + count - 1]));
        }
    }
    // Leaves of one group and merged subtrees of several (`bvh::collapse`) both occur.
    assert!(
        leaves > 3000 / (MAX_MERGED_GROUPS * GROUP_WIDTH),
        "{leaves} leaves"
    );
    assert!(
        multi_group > 0 && multi_group < leaves,
        "{multi_group} of {leaves} leaves span several groups"
    );
    for (slot, &prim) in b.grouped_order.iter().enumerate() {
        assert_eq!(
            b.groups[slot / GROUP_WIDTH].triangle(slot % GROUP_WIDTH),
            tris[prim as usize]
        );
    }
    let mut nodes = b.wide.clone();
    let mut short = vec![0u32; b.grouped_order.len() - 1];
    assert_eq!(
        align_leaves(&mut nodes, &b.prim_order, &mut short),
        Err(BvhError::NodeCapacity {
            needed: b.grouped_order.len(),
            given: short.len()
        })
    );
    let mut out = vec![0u32; b.grouped_order.len()];
    assert_eq!(
        align_leaves(&mut nodes, &b.prim_order[..10], &mut out),
        Err(BvhError::Malformed)
    );
    let mut few = vec![TriangleGroup::default(); b.groups.len() - 1];
    assert!(matches!(
        gather_leaf_groups(&b.positions, &b.indices, &b.grouped_order, &mut few),
        Err(BvhError::NodeCapacity { .. })
    ));
    let mut groups = vec![TriangleGroup::default(); b.groups.len()];
    assert_eq!(
        gather_leaf_groups(&b.positions, &b.indices[..5], &b.grouped_order, &mut groups),
        Err(BvhError::Malformed)
    );
}
