//! Reading and writing files: EXR, NPY, PNG, JSON.
