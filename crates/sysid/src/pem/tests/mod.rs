//! Tests of the prediction-error method.

mod jacobian;
mod search;
