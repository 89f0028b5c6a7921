//! Built-in materials.
