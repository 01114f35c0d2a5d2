//! Properties of the transfers: conservation, nothing from nothing, kernels, bilinear.

use deepcontact_core::Vector;
use deepcontact_grid::{G2pMethod, GridSpec, Kernel, NeighbourSearch, Transfer};
use proptest::prelude::*;

fn kernels(h: f64) -> [Kernel; 3] {
    [Kernel::Poly6, Kernel::Spiky, Kernel::gaussian_for(h)]
}

fn close(a: f64, b: f64, scale: f64) -> bool {
    (a - b).abs() <= 1e-9 * scale.max(1.0)
}

/// Particles strictly inside a 15 m box; values in [-5, 5] for 3 channels.
fn particles() -> impl Strategy<Value = (Vec<(f64, f64)>, Vec<f64>)> {
    (1usize..60).prop_flat_map(|n| {
        (
            prop::collection::vec((0.0..15.0f64, 0.0..15.0f64), n),
            prop::collection::vec(-5.0..5.0f64, 3 * n),
        )
    })
}

fn channel_totals(grid: &[f64], channels: usize) -> Vec<f64> {
    let n = grid.len() / channels;
    (0..channels)
        .map(|c| grid[c * n..(c + 1) * n].iter().sum())
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, failure_persistence: None, ..ProptestConfig::default() })]

    /// With h ≥ spacing / √2 every particle inside the grid has a node within h, so the
    /// grid total of every channel equals the particle total.
    #[test]
    fn p2g_conserves_every_channel(
        (pts, vals) in particles(),
        res in prop::sample::select(vec![0.125, 0.25, 0.5]),
        h_factor in 0.75..3.0f64,
        kd in any::<bool>(),
    ) {
        let h = res * h_factor;
        let spec = GridSpec::covering(Vector::zeros(), Vector::new(15.0, 15.0), res).unwrap();
        let pos: Vec<Vector> = pts.iter().map(|&(x, y)| Vector::new(x, y)).collect();
        for kernel in kernels(h) {
            let search = if kd { NeighbourSearch::KdTree } else { NeighbourSearch::Exact };
            let mut t = Transfer::new(spec, kernel, h).unwrap().with_search(search);
            let mut grid = vec![0.0; 3 * spec.len()];
            let stats = t.particles_to_grid(&pos, &vals, 3, &mut grid).unwrap();
            prop_assert_eq!(stats.lost, 0);
            let totals = channel_totals(&grid, 3);
            for (c, &total) in totals.iter().enumerate() {
                let want: f64 = vals.iter().skip(c).step_by(3).sum();
                let scale: f64 = vals.iter().map(|v| v.abs()).sum();
                prop_assert!(close(total, want, scale), "{kernel} c={c}: {total} vs {want}");
            }
        }
    }

    /// Grid → particles never creates value: for a non-negative grid the particles
    /// receive at most the grid total, exactly the total of the nodes with a particle
    /// within h. After P2G of the same particles every non-zero node has one, so then
    /// the totals are equal.
    #[test]
    fn g2p_creates_nothing_from_nothing(
        (pts, vals) in particles(),
        grid_vals in prop::collection::vec((0usize..31 * 31, 0.0..3.0f64), 1..200),
        h in 0.3..1.2f64,
        kd in any::<bool>(),
    ) {
        let spec = GridSpec::covering(Vector::zeros(), Vector::new(15.0, 15.0), 0.5).unwrap();
        let n = spec.len();
        let pos: Vec<Vector> = pts.iter().map(|&(x, y)| Vector::new(x, y)).collect();
        let search = if kd { NeighbourSearch::KdTree } else { NeighbourSearch::Exact };
        let mut t = Transfer::new(spec, Kernel::Poly6, h).unwrap().with_search(search);

        // An arbitrary non-negative single-channel grid.
        let mut grid = vec![0.0; n];
        for &(i, v) in &grid_vals {
            grid[i] += v;
        }
        let mut out = vec![0.0; pos.len()];
        t.grid_to_particles(&grid, 1, &pos, &mut out).unwrap();
        let total: f64 = grid.iter().sum();
        let reached: f64 = (0..n)
            .filter(|&i| pos.iter().any(|p| (p - spec.node_at(i)).norm() < h))
            .map(|i| grid[i])
            .sum();
        let got: f64 = out.iter().sum();
        prop_assert!(got <= total * (1.0 + 1e-12) + 1e-12);
        prop_assert!(close(got, reached, total), "{got} vs {reached}");
        prop_assert!(out.iter().all(|&v| v >= 0.0));

        // P2G then G2P of the same particles: every node holding a value has a particle
        // within h, so each channel's grid total comes back in full (and equals the
        // particle total when no particle was lost; h < spacing / √2 may lose some).
        let mut grid3 = vec![0.0; 3 * n];
        let stats = t.particles_to_grid(&pos, &vals, 3, &mut grid3).unwrap();
        let totals = channel_totals(&grid3, 3);
        let mut back = vec![0.0; 3 * pos.len()];
        t.grid_to_particles(&grid3, 3, &pos, &mut back).unwrap();
        let scale: f64 = vals.iter().map(|v| v.abs()).sum();
        for (c, &total) in totals.iter().enumerate() {
            let want: f64 = vals.iter().skip(c).step_by(3).sum();
            let got: f64 = back.iter().skip(c).step_by(3).sum();
            prop_assert!(close(got, total, scale), "c={c}: {got} vs grid {total}");
            if stats.lost == 0 {
                prop_assert!(close(got, want, scale), "c={c}: {got} vs {want}");
            }
        }
        // The fused round trip gives the same values.
        let mut fused = vec![0.0; 3 * pos.len()];
        t.round_trip(&pos, &vals, 3, &mut fused).unwrap();
        for (a, b) in back.iter().zip(&fused) {
            prop_assert!(close(*a, *b, scale));
        }
    }

    /// Bilinear interpolation reproduces a linear field exactly inside the grid.
    #[test]
    fn bilinear_reproduces_linear_fields(
        pts in prop::collection::vec((-2.0..7.0f64, 1.0..9.0f64), 1..50),
        a in -3.0..3.0f64, b in -3.0..3.0f64, c in -3.0..3.0f64,
        res in 0.1..1.0f64,
    ) {
        let spec = GridSpec::covering(Vector::new(-2.0, 1.0), Vector::new(7.0, 9.0), res).unwrap();
        let mut t = Transfer::new(spec, Kernel::Poly6, res).unwrap().with_g2p(G2pMethod::Bilinear);
        let grid: Vec<f64> = (0..spec.len()).map(|i| { let p = spec.node_at(i); a + b * p.x + c * p.y }).collect();
        let pos: Vec<Vector> = pts.iter().map(|&(x, y)| Vector::new(x, y)).collect();
        let mut out = vec![0.0; pos.len()];
        t.grid_to_particles(&grid, 1, &pos, &mut out).unwrap();
        for (p, v) in pos.iter().zip(&out) {
            let want = a + b * p.x + c * p.y;
            prop_assert!((v - want).abs() < 1e-9, "{p:?}: {v} vs {want}");
        }
    }
}

/// The 2D integral of every kernel over a fine Cartesian grid is one, and the kernel is
/// zero beyond h.
#[test]
fn kernels_are_normalised_in_2d_and_compact() {
    for h in [0.125, 0.5, 1.0] {
        for k in kernels(h) {
            let m = 800;
            let d = 2.0 * h / m as f64;
            let mut sum = 0.0;
            for i in 0..m {
                for j in 0..m {
                    let x = -h + (i as f64 + 0.5) * d;
                    let y = -h + (j as f64 + 0.5) * d;
                    sum += k.value(x.hypot(y), h);
                }
            }
            let integral = sum * d * d;
            assert!((integral - 1.0).abs() < 2e-3, "{k} h={h}: {integral}");
            for r in [h * 1.0000001, 1.5 * h, 10.0 * h] {
                assert_eq!(k.value(r, h), 0.0, "{k} h={h} r={r}");
            }
            assert!(k.value(0.0, h) > 0.0);
            assert!(k.value(0.5 * h, h) > 0.0);
        }
    }
}

/// h below the spacing: particles between nodes have no node in range and are lost.
#[test]
fn support_smaller_than_spacing_loses_particles() {
    let spec = GridSpec::thesis();
    let mut t = Transfer::new(spec, Kernel::Poly6, 0.1).unwrap();
    let pos = [Vector::new(3.125, 3.125), Vector::new(3.0, 3.0)];
    let mut grid = vec![0.0; spec.len()];
    let stats = t
        .particles_to_grid(&pos, &[1.0, 2.0], 1, &mut grid)
        .unwrap();
    assert_eq!(stats.lost, 1);
    assert!((grid.iter().sum::<f64>() - 2.0).abs() < 1e-12);
}
