//! Local relaxation of a displacement field where it folds a surface.
//!
//! A displacement that varies faster than the surface curves (a normal offset deeper than the
//! radius of a ridge, or a coarse fit carried to the fine template by per-face frames where the
//! coarse triangles span a crease or the end of the forearm) turns faces over. A skin never
//! folds, so there the displacement of the folded faces' vertices and of their rings is averaged
//! with the neighbours' (half a uniform-Laplacian step on the 3D vectors, so that converging
//! normals cancel), and the test is repeated until no face folds; everywhere else the
//! displacement is left exactly as it was. This is the umbrella (uniform) Laplacian smoothing of
//! Taubin (1995, "A signal processing approach to fair surface design") restricted to where it
//! is needed, on the displacement rather than the positions, so that the shape underneath is
//! not shrunk.

use crate::geometry::{Topology, TriMesh, Vec3};

/// Relaxation passes [`relax_folds`] makes at most over a fixed neighbourhood by default.
pub const UNFOLD_PASSES: usize = 200;

/// Relaxation passes the fitted skin's unfolding makes at most while its neighbourhood widens
/// up to [`MAX_RELAX_RINGS`]: the widest folds a fit leaves at the palm's base take several
/// hundred.
pub const SKIN_UNFOLD_PASSES: usize = 1000;

/// Value `i` of `x` averaged with the mean of its ring's (half a uniform-Laplacian step); a
/// vertex without neighbours keeps its value.
pub(crate) fn half_ring_step<T>(x: &[T], rings: &[Vec<usize>], i: usize) -> T
where
    T: Copy
        + std::ops::Add<Output = T>
        + std::ops::Mul<f64, Output = T>
        + std::ops::Div<f64, Output = T>
        + std::iter::Sum<T>,
{
    let r = &rings[i];
    if r.is_empty() {
        return x[i];
    }
    x[i] * 0.5 + r.iter().map(|&j| x[j]).sum::<T>() / r.len() as f64 * 0.5
}

/// Passes [`relax_folds`] waits for the count of folded faces to fall before it widens the
/// neighbourhood it relaxes by one more ring.
pub const STALL_PASSES: usize = 10;

/// The widest neighbourhood the fitted skin's unfolding relaxes ([`relax_folds`]): the folded
/// faces' vertices and this many rings around them. A posed skin's is not widened: there the
/// folds are the skinning's own at a flexed crease, and a wide relaxation would move what the
/// segments' volume correction placed.
pub const MAX_RELAX_RINGS: usize = 16;

/// Relax the displacement `d` of `mesh` (whose [`Topology`] is `topology`) where
/// `folded(face, d)` says the displaced face folds: the displacement of every folded face's
/// vertices and of their rings takes a half ring step, and only the faces around a moved vertex
/// are tested again, for at most `max_passes` passes. Returns how many faces still fold.
///
/// Relaxing a fixed neighbourhood converges to the harmonic fill of the displacement around it,
/// which still folds where the field compresses the surface over a wider patch than the
/// neighbourhood (a fit pulling the palm's base in along a crease); so whenever the count of
/// folded faces has not fallen for [`STALL_PASSES`] passes, one more ring joins the
/// neighbourhood, up to `max_rings` (1: the fixed neighbourhood).
///
/// Input: a mesh, its topology, a displacement per vertex and a fold test. Output: the
/// displacement, changed only around folded faces; the count of faces left folded.
pub fn relax_folds(
    mesh: &TriMesh,
    topology: &Topology,
    d: &mut [Vec3],
    folded: impl Fn(usize, &[Vec3]) -> bool,
    max_passes: usize,
    max_rings: usize,
) -> usize {
    let rings = &topology.vertex_rings;
    let mut bad_faces: Vec<usize> = (0..mesh.n_faces()).filter(|&f| folded(f, d)).collect();
    let (mut width, mut fewest, mut stalled) = (1, bad_faces.len(), 0);
    for _ in 0..max_passes {
        if bad_faces.is_empty() {
            break;
        }
        let mut relax = vec![false; d.len()];
        let mut front: Vec<usize> = Vec::new();
        for &f in &bad_faces {
            for &v in &mesh.faces[f] {
                if !relax[v] {
                    relax[v] = true;
                    front.push(v);
                }
            }
        }
        for _ in 0..width {
            let mut next = Vec::new();
            for &v in &front {
                for &w in &rings[v] {
                    if !relax[w] {
                        relax[w] = true;
                        next.push(w);
                    }
                }
            }
            front = next;
        }
        let relaxed: Vec<usize> = (0..d.len()).filter(|&i| relax[i]).collect();
        let moved: Vec<Vec3> = relaxed
            .iter()
            .map(|&i| half_ring_step(d, rings, i))
            .collect();
        for (&i, x) in relaxed.iter().zip(moved) {
            d[i] = x;
        }
        // Only faces touching a moved vertex can have changed; every folded face is one.
        let mut touched: Vec<usize> = relaxed
            .iter()
            .flat_map(|&v| topology.vertex_faces[v].iter().copied())
            .collect();
        touched.sort_unstable();
        touched.dedup();
        bad_faces = touched.into_iter().filter(|&f| folded(f, d)).collect();
        if bad_faces.len() < fewest {
            (fewest, stalled) = (bad_faces.len(), 0);
        } else {
            stalled += 1;
            if stalled >= STALL_PASSES && width < max_rings {
                (width, stalled) = (width + 1, 0);
            }
        }
    }
    bad_faces.len()
}

/// Per face of `mesh`, its area-weighted normal turned by its own bone's rotation
/// (`rotations` per link, the bone being the dominant link of the face's first vertex,
/// `owners` per vertex): the direction a face of a skin posed by those bones must keep facing.
pub fn bone_carried_normals(
    mesh: &TriMesh,
    owners: &[usize],
    rotations: &[nalgebra::UnitQuaternion<f64>],
) -> Vec<Vec3> {
    mesh.faces
        .iter()
        .enumerate()
        .map(|(f, face)| rotations[owners[face[0]]] * mesh.face_cross(f))
        .collect()
}

/// How a face stands against the direction it must keep facing ([`face_turn`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FaceTurn {
    /// Facing within 90° of its guard.
    Kept,
    /// Turned over: more than 90° from its guard.
    Inverted,
    /// Its area lost: below 1e-6 of the guard's.
    Degenerate,
}

/// The fold rule: how a face whose area-weighted normal is `cross` stands against `guard`
/// (the same face's area-weighted normal as it must keep facing).
pub fn face_turn(guard: &Vec3, cross: &Vec3) -> FaceTurn {
    if cross.norm() <= 1e-6 * guard.norm() {
        FaceTurn::Degenerate
    } else if guard.dot(cross) < 0.0 {
        FaceTurn::Inverted
    } else {
        FaceTurn::Kept
    }
}

/// Whether a face whose area-weighted normal is `cross` has turned over (more than 90°) from
/// `guard`, or lost its area (below 1e-6 of the guard's): [`face_turn`] not kept.
pub fn turned_over(guard: &Vec3, cross: &Vec3) -> bool {
    face_turn(guard, cross) != FaceTurn::Kept
}

/// `skin` (homologous to `source`: the same faces) with its displacement from `source` relaxed
/// wherever a face of `skin` turned over from `skin_guard` (per face, the direction its normal
/// must keep facing, e.g. the template's face carried by its bone, [`bone_carried_normals`])
/// while the same face of `source` had not turned over from `source_guard`, for at most
/// `max_passes` passes over a neighbourhood widened up to `max_rings` ([`relax_folds`]).
/// Returns the faces found folded before and those left folded after.
///
/// A face already folded in `source` (a crease of the skinned template) is left alone: the
/// relaxation averages displacements, and cannot unfold what the shape underneath folds.
pub fn unfold_skin(
    source: &TriMesh,
    source_guard: &[Vec3],
    skin: &mut TriMesh,
    skin_guard: &[Vec3],
    topology: &Topology,
    max_passes: usize,
    max_rings: usize,
) -> (usize, usize) {
    let fine_before: Vec<bool> = (0..source.n_faces())
        .map(|f| !turned_over(&source_guard[f], &source.face_cross(f)))
        .collect();
    let folded = |f: usize, d: &[Vec3]| -> bool {
        if !fine_before[f] {
            return false;
        }
        let p = skin.faces[f].map(|v| source.vertices[v] + d[v]);
        turned_over(&skin_guard[f], &(p[1] - p[0]).cross(&(p[2] - p[0])))
    };
    let mut d: Vec<Vec3> = skin
        .vertices
        .iter()
        .zip(&source.vertices)
        .map(|(s, t)| s - t)
        .collect();
    let before = (0..skin.n_faces()).filter(|&f| folded(f, &d)).count();
    if before == 0 {
        return (0, 0);
    }
    let after = relax_folds(source, topology, &mut d, folded, max_passes, max_rings);
    for ((v, t), x) in skin.vertices.iter_mut().zip(&source.vertices).zip(&d) {
        *v = t + x;
    }
    (before, after)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Point;

    /// [`unfold_skin`] over the fixed neighbourhood, one guard for both meshes.
    fn unfold_fixed(
        source: &TriMesh,
        guard: &[Vec3],
        skin: &mut TriMesh,
        topology: &Topology,
    ) -> (usize, usize) {
        unfold_skin(source, guard, skin, guard, topology, UNFOLD_PASSES, 1)
    }

    /// A flat grid whose middle vertex is pushed through its neighbours (its six faces turn
    /// over): relaxed, no face folds, the vertices far from the fold keep their displacement
    /// exactly, and the pushed vertex ends between its neighbours' heights.
    #[test]
    fn a_pushed_vertex_is_unfolded_and_the_rest_kept() {
        let n = 9;
        let source =
            crate::geometry::mesh::tests::grid(n - 1, Point::origin(), Vec3::x(), Vec3::y());
        let topology = source.topology();
        let guard: Vec<Vec3> = (0..source.n_faces())
            .map(|f| source.face_cross(f))
            .collect();
        // Everything lifted by 2 mm, the middle vertex moved sideways past its ring.
        let mid = 4 * n + 4;
        let mut skin = source.clone();
        for v in skin.vertices.iter_mut() {
            v.z += 2.0;
        }
        skin.vertices[mid].x += 1.6;
        skin.vertices[mid].y += 1.6;
        let turned = |m: &TriMesh| {
            (0..m.n_faces())
                .filter(|&f| guard[f].dot(&m.face_cross(f)) <= 0.0)
                .count()
        };
        let folded = turned(&skin);
        assert!(folded > 0);
        let (before, after) = unfold_fixed(&source, &guard, &mut skin, &topology);
        assert_eq!((before, after), (folded, 0));
        assert_eq!(turned(&skin), 0);
        // Two rings or more away, untouched; the uniform lift everywhere.
        for (k, v) in skin.vertices.iter().enumerate() {
            let (i, j) = ((k % n) as i64, (k / n) as i64);
            assert!((v.z - 2.0).abs() < 1e-12, "vertex {k}");
            if (i - 4).abs().max((j - 4).abs()) > 3 {
                assert_eq!(*v, source.vertices[k] + Vec3::new(0.0, 0.0, 2.0));
            }
        }
    }

    /// A band of a flat grid mirrored across its middle and stretched (x -> x0 - 2 (x - x0)
    /// within 5 of x0, carried on as a translation beyond): every face of the band turns over.
    /// Relaxing the folded faces and one ring stalls within the fitted skin's passes: the
    /// straight fill between the displacements one ring out has the slope 3·5/(5+1) and still
    /// mirrors the band. With the neighbourhood widened whenever the count stalls no face
    /// folds, and the grid beyond what the unfolding needs keeps its displacement bit for bit.
    #[test]
    fn a_fold_wider_than_a_ring_is_unfolded_by_widening() {
        let k = 60;
        let n = k + 1;
        let mesh = crate::geometry::mesh::tests::grid(k, Point::origin(), Vec3::x(), Vec3::y());
        let topology = mesh.topology();
        let (x0, w, gain) = (30.0, 5.0, 3.0);
        let field = |x: f64| Vec3::new(-gain * (x - x0).clamp(-w, w), 0.0, 0.0);
        let mut d: Vec<Vec3> = mesh.vertices.iter().map(|v| field(v.x)).collect();
        let want = d.clone();
        let folded = |f: usize, d: &[Vec3]| {
            let p = mesh.faces[f].map(|v| mesh.vertices[v] + d[v]);
            mesh.face_cross(f).dot(&(p[1] - p[0]).cross(&(p[2] - p[0]))) <= 0.0
        };
        let before = (0..mesh.n_faces()).filter(|&f| folded(f, &d)).count();
        assert_eq!(
            before,
            2 * 10 * k,
            "the band's ten columns of faces turn over"
        );
        let mut fixed = d.clone();
        let stalled = relax_folds(&mesh, &topology, &mut fixed, folded, SKIN_UNFOLD_PASSES, 1);
        assert!(stalled > before / 2, "{stalled} of {before} left folded");
        let left = relax_folds(
            &mesh,
            &topology,
            &mut d,
            folded,
            SKIN_UNFOLD_PASSES,
            MAX_RELAX_RINGS,
        );
        assert_eq!(left, 0);
        assert_eq!((0..mesh.n_faces()).filter(|&f| folded(f, &d)).count(), 0);
        // Undoing the band's mirror spreads its 30 mm at a slope below one over some 25 columns
        // each side; the grid's outermost columns keep their translation bit for bit.
        for (v, (got, want)) in d.iter().zip(&want).enumerate() {
            if (v % n).abs_diff(30) >= 28 {
                assert_eq!(got, want, "vertex {v}");
            }
        }
    }

    /// A displacement that folds nothing is returned unchanged, bit for bit.
    #[test]
    fn nothing_folded_nothing_moved() {
        let source = crate::geometry::mesh::tests::icosphere(10.0, 2);
        let topology = source.topology();
        let guard: Vec<Vec3> = (0..source.n_faces())
            .map(|f| source.face_cross(f))
            .collect();
        let mut skin = source.clone();
        for v in skin.vertices.iter_mut() {
            *v = Point::from(v.coords * 1.1 + Vec3::new(0.3, -0.2, 0.1));
        }
        let want = skin.clone();
        assert_eq!(unfold_fixed(&source, &guard, &mut skin, &topology), (0, 0));
        assert_eq!(skin.vertices, want.vertices);
    }
}
