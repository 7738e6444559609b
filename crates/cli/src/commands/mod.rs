//! One module per subcommand.

pub mod c2d;
pub mod closed_loop;
pub mod codegen;
pub mod empc;
pub mod export;
pub mod fgm;
pub mod identify;
pub mod import;
pub mod kalman;
pub mod mpc;
pub mod pipeline;
pub mod problem_thetas;
pub mod qp;
pub mod scalar_arg;
pub mod simulate;
pub mod tricopter_names;
