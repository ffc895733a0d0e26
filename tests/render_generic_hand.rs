//! Visual check of Loop subdivision and the renderer on the vendored generic hand.
//! Run with `cargo test --test render_generic_hand -- --ignored`; the picture goes to
//! `$ERGOHAND_RENDER_OUT` (default: `generic-hand-views.png` in the system temp folder).

use ergohand::geometry::loop_subdivision::loop_subdivide_n;
use ergohand::geometry::{Point, TriMesh, Vec3};
use ergohand::render::{
    colour_bar, compose_grid, draw_label, draw_points, draw_segments, map_values, render_mesh,
    render_mesh_with, RenderOptions, Shading, View,
};

/// The right generic hand in mm, welded at its texture seams.
fn generic_hand() -> TriMesh {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/generic-hand/right.glb");
    let (doc, buffers, _) = gltf::import(path).unwrap();
    let mut vertices = Vec::new();
    let mut faces = Vec::new();
    for mesh in doc.meshes() {
        for prim in mesh.primitives() {
            let reader = prim.reader(|b| Some(&buffers[b.index()]));
            let base = vertices.len();
            vertices.extend(
                reader
                    .read_positions()
                    .unwrap()
                    .map(|p| Point::new(p[0] as f64, p[1] as f64, p[2] as f64) * 1000.0),
            );
            let idx: Vec<usize> = reader
                .read_indices()
                .unwrap()
                .into_u32()
                .map(|i| i as usize)
                .collect();
            faces.extend(
                idx.chunks(3)
                    .map(|c| [base + c[0], base + c[1], base + c[2]]),
            );
        }
    }
    let (welded, _) = TriMesh::new(vertices, faces).unwrap().weld(0.0);
    welded
}

#[test]
#[ignore]
fn render_generic_hand_views() {
    let hand = generic_hand();
    hand.check_closed_manifold().unwrap();
    let sub = loop_subdivide_n(&hand, 2);
    sub.mesh.check_closed_manifold().unwrap();
    let c = hand.vertex_centroid();
    // Fingers point along −Y: put them at the top of every view.
    let up = -Vec3::y();
    let dirs = [
        ("along -z", -Vec3::z()),
        ("along +z", Vec3::z()),
        ("along +x", Vec3::x()),
        ("along -x", -Vec3::x()),
    ];
    let (w, h) = (360, 480);
    let tips: Vec<Point> = (0..5)
        .map(|k| {
            // A few extreme vertices as stand-in landmarks: the lowest-y vertex per x-slab.
            let (lo, hi) = hand.bounds().unwrap();
            let x0 = lo.x + (hi.x - lo.x) * k as f64 / 5.0;
            let x1 = lo.x + (hi.x - lo.x) * (k + 1) as f64 / 5.0;
            *sub.mesh
                .vertices
                .iter()
                .filter(|p| p.x >= x0 && p.x <= x1)
                .min_by(|a, b| a.y.total_cmp(&b.y))
                .unwrap()
        })
        .collect();
    let bones: Vec<[Point; 2]> = tips.iter().map(|t| [c, *t]).collect();
    let mut views = Vec::new();
    for (name, d) in dirs {
        let view = View::along(d, up).fit_mesh(&sub.mesh, 0.05);
        let mut img = render_mesh(&sub.mesh, None, &view, w, h);
        draw_segments(&mut img, &view, &bones, 2.0, [40, 60, 200], true);
        draw_points(&mut img, &view, &tips, 4.0, [220, 40, 40], false);
        draw_label(&mut img, 8, 8, name, [0, 0, 0]).unwrap();
        views.push(img);
    }
    // Flat shading with wireframe of the control mesh, and a colour map of the distance moved
    // by subdivision (original vertices only: 0..n keep their indices).
    let view = View::along(-Vec3::z(), up).fit_mesh(&hand, 0.05);
    let flat = RenderOptions {
        shading: Shading::Flat,
        wireframe: Some([60, 60, 60]),
        ..Default::default()
    };
    let mut img = render_mesh_with(&hand, None, &view, w, h, &flat);
    draw_label(&mut img, 8, 8, "control mesh", [0, 0, 0]).unwrap();
    views.push(img);
    let moved: Vec<f64> = sub
        .apply(
            &hand
                .vertices
                .iter()
                .map(|p| p.coords)
                .collect::<Vec<Vec3>>(),
        )
        .iter()
        .zip(&sub.mesh.vertices)
        .map(|(a, b)| (a - b.coords).norm())
        .collect();
    assert!(
        moved.iter().all(|&d| d < 1e-9),
        "stencil reproduces positions"
    );
    let radial: Vec<f64> = sub.mesh.vertices.iter().map(|p| (p - c).norm()).collect();
    let (lo, hi) = (
        radial.iter().cloned().fold(f64::INFINITY, f64::min),
        radial.iter().cloned().fold(0.0, f64::max),
    );
    let colours = map_values(&radial, lo, hi);
    let mut img = render_mesh(&sub.mesh, Some(&colours), &view, w, h);
    draw_label(&mut img, 8, 8, "distance to centroid", [0, 0, 0]).unwrap();
    views.push(img);
    views.push(colour_bar(lo, hi, 160, h).unwrap());
    let sheet = compose_grid(&views, 4);
    let out = std::env::var_os("ERGOHAND_RENDER_OUT")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::env::temp_dir().join("generic-hand-views.png"));
    sheet.save_png(&out).unwrap();
    eprintln!("wrote {}", out.display());
}
