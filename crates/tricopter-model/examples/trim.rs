//! Prints the hover trim of the default aircraft, like (7.2) of the thesis.
use kestrel_tricopter_model::{Params, Tricopter};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let model = Tricopter::new(Params::default())?;
    println!("{}", model.trim_hover()?);
    Ok(())
}
