//! placeholder
/// x
pub trait TreeTables {}
/// x
pub struct SliceTables;
/// x
pub struct Evaluation;
/// x
pub fn evaluate() {}
