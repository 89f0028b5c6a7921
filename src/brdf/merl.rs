//! MERL measured BRDF tables (`.binary`).
