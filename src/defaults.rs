//! Built-in default scene parts: a procedural HDR environment (sky, sun, ground).
