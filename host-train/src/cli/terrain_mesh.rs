//! The ground as a triangle mesh for a 3D viewer: the terrain's own height grid (the
//! points the simulator's heightfield is made of) inside an area, or a square for the
//! flat plane.

use host_sim::terrain::Terrain;

/// A triangle mesh, world frame.
#[derive(Clone, Debug, Default)]
pub struct TriangleMesh {
    /// Vertex positions, m.
    pub positions_m: Vec<[f32; 3]>,
    /// Unit vertex normals.
    pub normals: Vec<[f32; 3]>,
    /// Triangles (indices into the vertices), counter-clockwise seen from above.
    pub triangles: Vec<[u32; 3]>,
}

/// The ground inside `area_m` (x min, y min, x max, y max): the height grid's points in it
/// (at least one cell, clamped to the grid), two triangles per cell; for flat ground, one
/// square at z = 0.
pub fn terrain_mesh(terrain: &Terrain, area_m: [f32; 4]) -> TriangleMesh {
    let [x0, y0, x1, y1] = area_m;
    if terrain.heights_m.is_empty() {
        return TriangleMesh {
            positions_m: vec![[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]],
            normals: vec![[0.0, 0.0, 1.0]; 4],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        };
    }
    let cell = terrain.config.cell_size_m;
    let span = |lo: f32, hi: f32, n: usize| {
        let a = ((lo / cell).floor().max(0.0) as usize).min(n - 2);
        let b = ((hi / cell).ceil().max(0.0) as usize).clamp(a + 1, n - 1);
        (a, b)
    };
    let (ix0, ix1) = span(x0, x1, terrain.nx);
    let (iy0, iy1) = span(y0, y1, terrain.ny);
    let h = |ix: usize, iy: usize| terrain.heights_m[ix * terrain.ny + iy];
    let (cols, rows) = (iy1 - iy0 + 1, ix1 - ix0 + 1);
    let mut mesh = TriangleMesh::default();
    for ix in ix0..=ix1 {
        for iy in iy0..=iy1 {
            mesh.positions_m
                .push([ix as f32 * cell, iy as f32 * cell, h(ix, iy)]);
            // Central differences of the grid (one-sided at its edges).
            let (xa, xb) = (ix.saturating_sub(1), (ix + 1).min(terrain.nx - 1));
            let (ya, yb) = (iy.saturating_sub(1), (iy + 1).min(terrain.ny - 1));
            let dx = (h(xb, iy) - h(xa, iy)) / ((xb - xa) as f32 * cell);
            let dy = (h(ix, yb) - h(ix, ya)) / ((yb - ya) as f32 * cell);
            let norm = (dx * dx + dy * dy + 1.0).sqrt();
            mesh.normals.push([-dx / norm, -dy / norm, 1.0 / norm]);
        }
    }
    let vertex = |i: usize, j: usize| (i * cols + j) as u32;
    for i in 0..rows - 1 {
        for j in 0..cols - 1 {
            let (v00, v10, v01, v11) = (
                vertex(i, j),
                vertex(i + 1, j),
                vertex(i, j + 1),
                vertex(i + 1, j + 1),
            );
            mesh.triangles.push([v00, v10, v11]);
            mesh.triangles.push([v00, v11, v01]);
        }
    }
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;
    use host_sim::terrain::TerrainConfig;

    #[test]
    fn flat_ground_is_one_square() {
        let flat = Terrain::generate(&TerrainConfig::default());
        let mesh = terrain_mesh(&flat, [-1.0, -2.0, 3.0, 4.0]);
        assert_eq!(mesh.positions_m.len(), 4);
        assert_eq!(mesh.triangles.len(), 2);
        assert!(mesh.positions_m.contains(&[3.0, 4.0, 0.0]));
    }

    #[test]
    fn grid_mesh_carries_the_heights() {
        let cell = 0.1;
        let (nx, ny) = (20, 10);
        let heights: Vec<f32> = (0..nx * ny)
            .map(|k| if k / ny >= 10 { 0.15 } else { 0.0 })
            .collect();
        let terrain = Terrain::from_heights(cell, nx, ny, heights);
        let mesh = terrain_mesh(&terrain, [0.25, 0.05, 1.42, 0.45]);
        // x from grid point 2 to 15, y from 0 to 5.
        assert_eq!(mesh.positions_m.len(), 14 * 6);
        assert_eq!(mesh.triangles.len(), 2 * 13 * 5);
        for p in &mesh.positions_m {
            assert!(
                (p[2] - terrain.height_at_m(p[0], p[1])).abs() < 1e-4,
                "{p:?}"
            );
        }
        for n in &mesh.normals {
            assert!(
                ((n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() - 1.0).abs() < 1e-5 && n[2] > 0.0
            );
        }
        // Every triangle faces up (counter-clockwise seen from above).
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| mesh.positions_m[i as usize]);
            let cross_z = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
            assert!(cross_z > 0.0);
        }
        // An area off the grid still gets one cell at its edge.
        assert_eq!(
            terrain_mesh(&terrain, [5.0, 5.0, 6.0, 6.0]).triangles.len(),
            2
        );
    }
}
