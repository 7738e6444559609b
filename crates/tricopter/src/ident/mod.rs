//! Identification of the tricopter (section 7.4 of the thesis): the
//! simulated flights no. 2 and 3, the thesis's estimation and validation
//! sets and the black-box set-up ([`thesis_spec`], [`identify_thesis_model`]),
//! and the grey-box estimation of the physical parameters ([`greybox`]).

mod flights;
pub mod greybox;

pub use flights::{
    ESTIMATE, ModelKind, VALIDATE, VIRTUAL_ESTIMATE_THESIS, VIRTUAL_VALIDATE_THESIS,
    identify_thesis_model, prediction_spec, simulated_flights, thesis_spec, virtual_input_map,
};
