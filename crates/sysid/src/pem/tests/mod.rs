//! Tests of the prediction-error method.

mod jacobian;
mod normal;
mod search;
