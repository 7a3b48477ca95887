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
//! The data flow one way: [`case`] → [`mesh`] → [`assembly`] → [`contact`] (the reduced
//! variational inequality (3.4)) → [`action`] (λ_h by the local postprocessing (4.5)) →
//! [`flux`] (the H(div) reconstruction (4.13)) → [`norms`] → [`io`]. [`run`] strings them together;
//! [`study`] repeats a run over refined meshes.

pub mod action;
pub mod assembly;
pub mod case;
pub mod contact;
pub mod expr;
pub mod flux;
pub mod io;
pub mod linear;
pub mod mesh;
pub mod norms;
mod quadrature_tables;
pub mod run;
pub mod study;
