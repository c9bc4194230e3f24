//! Reports that reproduce the paper against Mitsuba 3 references: `table` (Table 1:
//! equal-time MSE of the regularized method, plain volpath and Mitsuba 3's volpath),
//! with `metrics` (MSE against a reference with its own variance) and `paper` (the
//! paper's published numbers, side by side), `figures`, and `sweep` (Table 1's methods
//! across budgets).

pub mod decompose;
pub mod figures;
pub mod html;
pub mod metrics;
pub mod mitsuba;
pub mod output;
pub mod paper;
pub mod plot;
pub mod reference;
pub mod row;
pub mod summary;
pub mod sweep;
pub mod table;

pub use summary::Summary;
pub use table::{
    run_scene, run_table, Accounting, Budget, Method, Row, SceneJob, TableOptions, TableRun,
};
