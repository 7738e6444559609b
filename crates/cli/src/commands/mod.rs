//! One module per subcommand.

pub mod c2d;
