pub use mocomp_codec as codec;
