//! The block-diagonal structure of a square matrix: the connected components of its sparsity
//! graph (`i ~ j` when `a_ij ≠ 0` or `a_ji ≠ 0`, exact zeros only). A model in modal form
//! (rigid body and one 2×2 block per mode, as `crate::stage` builds it and as ZOH keeps it) has
//! one component per block, so `e^{A h}` and the powers of `A` are computed block by block:
//! O(Σ nᵢ³) instead of O(n³), with the same formula per block (no approximation).

use nalgebra::DMatrix;

/// The components of `a`'s sparsity graph, each as its sorted indices, in the order of their
/// smallest index (one component holding every index when `a` is irreducible).
pub fn components(a: &DMatrix<f64>) -> Vec<Vec<usize>> {
    let n = a.nrows().min(a.ncols());
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for j in 0..n {
        for i in 0..n {
            if i != j && a[(i, j)] != 0.0 {
                let (ri, rj) = (root(&mut parent, i), root(&mut parent, j));
                if ri != rj {
                    parent[ri.max(rj)] = ri.min(rj);
                }
            }
        }
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut slot = vec![usize::MAX; n];
    for i in 0..n {
        let r = root(&mut parent, i);
        if slot[r] == usize::MAX {
            slot[r] = groups.len();
            groups.push(Vec::new());
        }
        groups[slot[r]].push(i);
    }
    groups
}

/// Writes a block's results into the whole: `x[g, g] = xg` and `y[g, :] = yg` (`g` the
/// block's indices).
pub fn scatter(
    (x, y): (&mut DMatrix<f64>, &mut DMatrix<f64>),
    g: &[usize],
    (xg, yg): (&DMatrix<f64>, &DMatrix<f64>),
) {
    for (p, &i) in g.iter().enumerate() {
        for (q, &j) in g.iter().enumerate() {
            x[(i, j)] = xg[(p, q)];
        }
        y.row_mut(i).copy_from(&yg.row(p));
    }
}

/// Whether splitting by [`components`] pays: more than one component and none above half the
/// dimension.
pub fn worth_splitting(groups: &[Vec<usize>], n: usize) -> bool {
    groups.len() > 1 && groups.iter().all(|g| 2 * g.len() <= n.max(1))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn modal_blocks_and_a_coupled_matrix() {
        // blocks {0, 3} and {1, 2}, and an isolated 4
        let mut a = DMatrix::zeros(5, 5);
        a[(0, 3)] = 1.0;
        a[(3, 0)] = -4.0;
        a[(1, 2)] = 2.0;
        a[(4, 4)] = -1.0;
        assert_eq!(components(&a), vec![vec![0, 3], vec![1, 2], vec![4]]);
        assert!(worth_splitting(&components(&a), 5));
        let full = DMatrix::from_element(3, 3, 1.0);
        assert_eq!(components(&full), vec![vec![0, 1, 2]]);
        assert!(!worth_splitting(&components(&full), 3));
    }
}
