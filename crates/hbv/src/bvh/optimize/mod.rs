//! Optimizers: improve a built tree in place.

mod collapse;
mod reinsertion;
