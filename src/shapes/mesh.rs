//! The triangle mesh: positions, optional per-vertex normals, triangles; its checks, its
//! vertex normals, and the geometry the rasteriser and the shape generators share.

use rayon::slice::ParallelSliceMut;

use crate::error::{Error, Result};

/// `degrees` if it is a crease angle ([`Mesh::creased`]): in (0, 180]; else the message.
pub fn check_crease(degrees: f64) -> std::result::Result<f64, String> {
    if degrees > 0.0 && degrees <= 180.0 {
        Ok(degrees)
    } else {
        Err(format!("{degrees} is not an angle in (0, 180] degrees"))
    }
}

/// A triangle mesh. Triangles index `positions` (and `normals`, which, when given, has one
/// normal per position). Winding does not matter: the rasteriser turns every normal
/// towards the viewer.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Per-vertex normals (any length but 0; normalised where used), one per position.
    pub normals: Option<Vec<[f32; 3]>>,
    /// Vertex indices, three per triangle.
    pub triangles: Vec<[u32; 3]>,
}

pub(crate) type V3 = [f64; 3];

pub(crate) fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

pub(crate) fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

pub(crate) fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `a` / |a|, or `None` where |a| is 0 (or not finite).
pub(crate) fn unit(a: V3) -> Option<V3> {
    let len = dot(a, a).sqrt();
    (len > 0.0 && len.is_finite()).then(|| scale(a, 1.0 / len))
}

pub(crate) fn widen(p: [f32; 3]) -> V3 {
    p.map(f64::from)
}

const AXES: [char; 3] = ['x', 'y', 'z'];

impl Mesh {
    /// A checked mesh: see [`Mesh::validate`].
    pub fn new(
        positions: Vec<[f32; 3]>,
        normals: Option<Vec<[f32; 3]>>,
        triangles: Vec<[u32; 3]>,
    ) -> Result<Self> {
        let m = Mesh {
            positions,
            normals,
            triangles,
        };
        m.validate().map_err(Error::Invalid)?;
        Ok(m)
    }

    /// Checks that there is a triangle, that every index is in range, that the vertices
    /// the triangles use have finite coordinates (and finite normals, when given) and that
    /// they do not all sit at one point. The message names the first face at fault, e.g.
    /// `face 12: vertex index 900 out of range (812 vertices)` (faces count from 0);
    /// loaders put the file's name in front.
    pub fn validate(&self) -> std::result::Result<(), String> {
        if self.triangles.is_empty() {
            return Err("the mesh has no triangles".into());
        }
        let n = self.positions.len();
        if let Some(normals) = &self.normals
            && normals.len() != n
        {
            return Err(format!("{} vertex normals for {n} vertices", normals.len()));
        }
        for (f, tri) in self.triangles.iter().enumerate() {
            for &v in tri {
                let v = v as usize;
                if v >= n {
                    return Err(format!(
                        "face {f}: vertex index {v} out of range ({n} vertices)"
                    ));
                }
                if let Some(c) = self.positions[v].iter().position(|c| !c.is_finite()) {
                    return Err(format!(
                        "face {f}: vertex {v}: coordinate {} is {}",
                        AXES[c],
                        non_finite(self.positions[v][c])
                    ));
                }
                if let Some(normals) = &self.normals
                    && let Some(c) = normals[v].iter().position(|c| !c.is_finite())
                {
                    return Err(format!(
                        "face {f}: vertex {v}: normal component {} is {}",
                        AXES[c],
                        non_finite(normals[v][c])
                    ));
                }
            }
        }
        let (lo, hi) = self.bounds();
        if (0..3).all(|k| hi[k] - lo[k] <= 0.0) {
            return Err(format!(
                "every vertex is at ({}, {}, {}): the mesh has no extent",
                lo[0], lo[1], lo[2]
            ));
        }
        Ok(())
    }

    /// The bounding box (min, max) of the vertices the triangles use.
    pub fn bounds(&self) -> (V3, V3) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for tri in &self.triangles {
            for &v in tri {
                if let Some(p) = self.positions.get(v as usize) {
                    for k in 0..3 {
                        lo[k] = lo[k].min(f64::from(p[k]));
                        hi[k] = hi[k].max(f64::from(p[k]));
                    }
                }
            }
        }
        (lo, hi)
    }

    /// The normals the rasteriser interpolates: the given ones, else [`Mesh::smooth_normals`].
    pub fn vertex_normals(&self) -> Vec<[f32; 3]> {
        match &self.normals {
            Some(n) => n.clone(),
            None => self.smooth_normals(),
        }
    }

    /// Area-weighted vertex normals: each vertex gets the sum of the (unnormalised) face
    /// normals of the triangles around it, normalised, with the triangles' windings made
    /// to agree first ([`Mesh::winding_signs`]): a file whose faces are wound every which
    /// way gets the normals of its surface, not sums that cancel. A vertex that no
    /// triangle with an area uses gets [0, 0, 0] (the rasteriser then takes the face
    /// normal).
    pub fn smooth_normals(&self) -> Vec<[f32; 3]> {
        let signs = self.winding_signs();
        let mut sum = vec![[0.0f64; 3]; self.positions.len()];
        for (tri, &sign) in self.triangles.iter().zip(&signs) {
            let [a, b, c] = tri.map(|v| widen(self.positions[v as usize]));
            let n = scale(cross(sub(b, a), sub(c, a)), sign);
            for &v in tri {
                sum[v as usize] = add(sum[v as usize], n);
            }
        }
        sum.into_iter()
            .map(|n| unit(n).map_or([0.0; 3], |u| u.map(|c| c as f32)))
            .collect()
    }

    /// The mesh with its sharp edges kept, as a modeller's "auto smooth" does: each corner
    /// of a triangle gets the area-weighted mean of the face normals, around its vertex, of
    /// the triangles whose face normal is within `degrees` of its own (windings made to
    /// agree first, [`Mesh::winding_signs`]), and a vertex is split into one per normal
    /// its corners get. A cube's eight corners become 24, its faces flat; a finely
    /// tessellated sphere keeps [`Mesh::smooth_normals`]. A mesh with normals of its own
    /// keeps them (returned as it is). A corner of a triangle without an area gets
    /// [0, 0, 0] (the rasteriser then takes the face normal). `degrees`: see
    /// [`check_crease`].
    pub fn creased(&self, degrees: f64) -> Mesh {
        if self.normals.is_some() {
            return self.clone();
        }
        let signs = self.winding_signs();
        // unnormalised face normals (their length is twice the area) and unit ones
        let face: Vec<V3> = (self.triangles.iter().zip(&signs))
            .map(|(tri, &sign)| {
                let [a, b, c] = tri.map(|v| widen(self.positions[v as usize]));
                scale(cross(sub(b, a), sub(c, a)), sign)
            })
            .collect();
        let dir: Vec<Option<V3>> = face.iter().map(|&f| unit(f)).collect();
        let mut around: Vec<Vec<u32>> = vec![Vec::new(); self.positions.len()];
        for (t, tri) in self.triangles.iter().enumerate() {
            for &v in tri {
                around[v as usize].push(t as u32);
            }
        }
        let cos = degrees.to_radians().cos();
        let mut index = std::collections::HashMap::new();
        let (mut positions, mut normals) = (Vec::new(), Vec::new());
        let triangles = (self.triangles.iter().enumerate())
            .map(|(t, tri)| {
                tri.map(|v| {
                    let n = dir[t].and_then(|own| {
                        let near = around[v as usize]
                            .iter()
                            .filter(|&&u| dir[u as usize].is_some_and(|d| dot(d, own) >= cos));
                        unit(near.fold([0.0; 3], |sum, &u| add(sum, face[u as usize])))
                    });
                    let n = n.map_or([0.0f32; 3], |n| n.map(|c| c as f32));
                    *index.entry((v, n.map(f32::to_bits))).or_insert_with(|| {
                        positions.push(self.positions[v as usize]);
                        normals.push(n);
                        (positions.len() - 1) as u32
                    })
                })
            })
            .collect();
        Mesh {
            positions,
            normals: Some(normals),
            triangles,
        }
    }

    /// Per triangle, 1 or -1: the signs that make the windings agree, found by walking from
    /// each connected part's first triangle across the edges that exactly two triangles
    /// share (agreeing windings run a shared edge in opposite directions). All 1 where the
    /// windings already agree, without the walk. An edge of three or more triangles joins
    /// none of them; a surface that cannot be oriented (a Moebius strip) keeps the first
    /// sign each triangle gets.
    pub fn winding_signs(&self) -> Vec<f64> {
        let n = self.triangles.len();
        // every edge (low vertex, high vertex, triangle, whether it runs low -> high)
        let mut edges: Vec<(u32, u32, u32, bool)> = Vec::with_capacity(3 * n);
        for (t, tri) in self.triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                if a != b {
                    edges.push((a.min(b), a.max(b), t as u32, a < b));
                }
            }
        }
        edges.par_sort_unstable();
        // the pairs of triangles sharing an edge: (t, u, whether they disagree)
        let pairs: Vec<(u32, u32, bool)> = edges
            .chunk_by(|e, f| (e.0, e.1) == (f.0, f.1))
            .filter_map(|run| match run {
                [e, f] if e.2 != f.2 => Some((e.2, f.2, e.3 == f.3)),
                _ => None,
            })
            .collect();
        let mut signs = vec![1.0; n];
        if !pairs.iter().any(|p| p.2) {
            return signs;
        }
        let mut adjacent: Vec<Vec<(u32, bool)>> = vec![Vec::new(); n];
        for &(t, u, disagree) in &pairs {
            adjacent[t as usize].push((u, disagree));
            adjacent[u as usize].push((t, disagree));
        }
        let mut seen = vec![false; n];
        let mut stack = Vec::new();
        for start in 0..n {
            if seen[start] {
                continue;
            }
            seen[start] = true;
            stack.push(start);
            while let Some(t) = stack.pop() {
                for &(u, disagree) in &adjacent[t] {
                    let u = u as usize;
                    if !seen[u] {
                        seen[u] = true;
                        signs[u] = if disagree { -signs[t] } else { signs[t] };
                        stack.push(u);
                    }
                }
            }
        }
        signs
    }

    /// Appends `other`'s triangles and vertices. Normals are kept only if both have them.
    pub fn append(&mut self, other: &Mesh) {
        let offset = self.positions.len() as u32;
        self.normals = match (
            self.positions.is_empty(),
            self.normals.take(),
            &other.normals,
        ) {
            (true, _, Some(b)) => Some(b.clone()),
            (false, Some(mut a), Some(b)) => {
                a.extend_from_slice(b);
                Some(a)
            }
            _ => None,
        };
        self.positions.extend_from_slice(&other.positions);
        self.triangles
            .extend(other.triangles.iter().map(|t| t.map(|v| v + offset)));
    }

    /// The mesh with every position mapped by `p` and every normal by `n`.
    pub fn transformed(&self, p: impl Fn(V3) -> V3, n: impl Fn(V3) -> V3) -> Mesh {
        let f32s = |v: V3| v.map(|c| c as f32);
        Mesh {
            positions: self.positions.iter().map(|&v| f32s(p(widen(v)))).collect(),
            normals: self
                .normals
                .as_ref()
                .map(|ns| ns.iter().map(|&v| f32s(n(widen(v)))).collect()),
            triangles: self.triangles.clone(),
        }
    }
}

/// Splits face `face` (vertex indices as the file has them, from 0) into a triangle fan,
/// checking each index against `vertices`.
pub(crate) fn fan(
    face: usize,
    indices: &[i64],
    vertices: usize,
    out: &mut Vec<[u32; 3]>,
) -> std::result::Result<(), String> {
    if indices.len() < 3 {
        return Err(format!(
            "face {face}: a face needs at least 3 vertices, this one has {}",
            indices.len()
        ));
    }
    for &i in indices {
        if i < 0 || i as u64 >= vertices as u64 {
            return Err(format!(
                "face {face}: vertex index {i} out of range ({vertices} vertices)"
            ));
        }
    }
    for k in 1..indices.len() - 1 {
        out.push([indices[0], indices[k], indices[k + 1]].map(|i| i as u32));
    }
    Ok(())
}

fn non_finite(v: f32) -> &'static str {
    if v.is_nan() { "NaN" } else { "infinite" }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetra() -> Mesh {
        Mesh {
            positions: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            normals: None,
            triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        }
    }

    #[test]
    fn validation_names_the_face() {
        assert_eq!(tetra().validate(), Ok(()));
        let mut m = tetra();
        m.triangles[2][1] = 9;
        assert_eq!(
            m.validate(),
            Err("face 2: vertex index 9 out of range (4 vertices)".into())
        );
        let mut m = tetra();
        m.positions[3][1] = f32::NAN;
        assert_eq!(
            m.validate(),
            Err("face 1: vertex 3: coordinate y is NaN".into())
        );
        let mut m = tetra();
        m.positions = vec![[2.0; 3]; 4];
        assert!(m.validate().unwrap_err().contains("no extent"));
        let m = Mesh {
            triangles: vec![],
            ..tetra()
        };
        assert_eq!(m.validate(), Err("the mesh has no triangles".into()));
    }

    #[test]
    fn windings_made_to_agree() {
        let m = tetra();
        assert_eq!(m.winding_signs(), vec![1.0; 4]);
        let mut shuffled = m.clone();
        shuffled.triangles[1].swap(0, 1);
        shuffled.triangles[3].swap(1, 2);
        let signs = shuffled.winding_signs();
        // relative to the first triangle, the two rewound ones get -1
        assert_eq!(signs, vec![1.0, -1.0, 1.0, -1.0]);
        assert_eq!(shuffled.smooth_normals(), m.smooth_normals());
    }

    #[test]
    fn a_creased_cube_has_flat_faces() {
        // a cube whose faces share their corners, as CGAL's cube.off
        let p = |x: f32, y: f32, z: f32| [x, y, z];
        let positions = vec![
            p(-1., -1., -1.),
            p(1., -1., -1.),
            p(1., 1., -1.),
            p(-1., 1., -1.),
            p(-1., -1., 1.),
            p(1., -1., 1.),
            p(1., 1., 1.),
            p(-1., 1., 1.),
        ];
        let quads = [
            [0, 3, 2, 1],
            [4, 5, 6, 7],
            [0, 1, 5, 4],
            [2, 3, 7, 6],
            [1, 2, 6, 5],
            [0, 4, 7, 3],
        ];
        let triangles = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        let m = Mesh::new(positions, None, triangles).unwrap();
        let c = m.creased(40.0);
        assert_eq!(
            c.positions.len(),
            24,
            "each corner of the cube split in three"
        );
        let normals = c.normals.as_ref().unwrap();
        for tri in &c.triangles {
            let [a, b, d] = tri.map(|v| widen(c.positions[v as usize]));
            let f = unit(cross(sub(b, a), sub(d, a))).unwrap();
            for &v in tri {
                let n = widen(normals[v as usize]);
                assert!(
                    (dot(n, f).abs() - 1.0).abs() < 1e-6,
                    "a flat face: {n:?} against {f:?}"
                );
            }
        }
        // above every dihedral angle of the cube (90 degrees), the smooth normals again
        let all = m.creased(100.0);
        assert_eq!(all.positions.len(), 8);
        let smooth = m.smooth_normals();
        for (n, q) in all.normals.unwrap().iter().zip(&all.positions) {
            let v = m.positions.iter().position(|p| p == q).unwrap();
            assert!((dot(widen(*n), widen(smooth[v])) - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn smooth_normals_point_outwards() {
        let m = tetra();
        let n = m.smooth_normals();
        // vertex 3 (0, 0, 1): faces 1, 2, 3 around it
        let v = widen(n[3]);
        assert!(v[2] > 0.5 && (dot(v, v) - 1.0).abs() < 1e-6, "{v:?}");
        let v0 = widen(n[0]);
        assert!(v0.iter().all(|&c| c < 0.0), "{v0:?}");
    }
}
