//! The search tree over the regions (Tøndel, Johansen and Bemporad 2003):
//! the state ([`state`]), the two scoring methods ([`lp_method`],
//! [`sampled`]) and clipping ([`clipping`]).

mod clipping;
mod lp_method;
mod sampled;
mod state;

pub(super) use state::Builder;
