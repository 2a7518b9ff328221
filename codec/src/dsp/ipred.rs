//! (table to come)
