//! # membrane-contact
//!
//! P1 finite elements for the unilateral contact between two elastic membranes (Ben Belgacem,
//! Bernardi, Blouza, Vohralík, Part 1): on a polygon ω find u1, u2, λ with
//!
//! ```text
//! −μ1 Δu1 − λ = f1,   −μ2 Δu2 + λ = f2,   u1 − u2 ≥ 0,  λ ≥ 0,  (u1 − u2) λ = 0,
//! u1 = g ≥ 0 and u2 = 0 on ∂ω.
//! ```
//!
//! The data flow one way: [`case`] → [`mesh`] → [`problem`] (the discrete problem (3.4), assembled
//! by [`assembly`]) → [`contact`] (its solution, by [`linear`] solves) → [`action`] (λ_h by the local
//! postprocessing (4.5)) → [`norms`] and [`flux`] (the H(div) reconstruction (4.13)) → [`result`],
//! put in place whole by [`atomic`]. [`run`] strings them together; [`study`] repeats a run over
//! refined meshes; [`estimator`] bounds the error of a run, and [`adapt`] refines where it says.
//!
//! ## Glossary: the paper's symbols and their names here
//!
//! | paper | here |
//! |---|---|
//! | μ1, μ2, f1, f2, g | `Data::{mu1, mu2, f1, f2, g}` |
//! | T_h, ∂ω | `Mesh`, `Mesh::on_boundary` |
//! | data per physical group of a Gmsh mesh | `Datum`, `Pieces` ([`datum`]), `Groups` |
//! | S_h, D_a (Section 4.2) | `DualMesh`, its cells with `DualMesh::owner` = a |
//! | K_ab = ∫∇φ_b·∇φ_a | `DiscreteProblem::stiffness` |
//! | m_a = ∫φ_a = meas(D_a) | `DiscreteProblem::mass` |
//! | (f_i, φ_a) | `DiscreteProblem::{load1, load2}` |
//! | g_h | `DiscreteProblem::g_h` |
//! | u1h, u2h | `Solution::{u1, u2}` |
//! | w = u1h − u2h | `gap` |
//! | λ_a, λ_h (4.5) from membrane 1 (2) | `Action::lambda` (`lambda2`), the field `lambda` |
//! | the contact set | `contact` |
//! | t_ih (4.13) | `Flux`, the fields `t1_x`, `t1_y`, `div_t1`, … |
//! | ‖λ − λ_h‖_H⁻¹ | `hminus1_lambda` (`--hminus1`) |
//! | η, η_K (docs/a-posteriori.md) | `Estimate`, the attribute and cell field `estimator` (`--estimate`) |

#![warn(missing_docs)]

/// An error type that holds its message, which names the file, key or path concerned.
macro_rules! message_error {
    ($(#[$doc:meta])* $name:ident) => {
        $(#[$doc])*
        #[derive(Debug, Clone, PartialEq)]
        pub struct $name(pub String);

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(&self.0)
            }
        }

        impl std::error::Error for $name {}
    };
}

pub mod action;
pub mod adapt;
pub mod assembly;
pub mod atomic;
pub mod case;
pub mod cg;
pub mod contact;
pub mod datum;
pub mod estimator;
pub mod expr;
pub mod flux;
pub mod linear;
pub mod mesh;
pub mod multigrid;
pub mod norms;
pub mod pages;
pub mod parallel;
pub mod problem;
pub mod progress;
mod quadrature_tables;
pub mod result;
pub mod run;
pub mod sparse;
pub mod study;
