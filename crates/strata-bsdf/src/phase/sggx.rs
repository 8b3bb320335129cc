//! SGGX microflake phase functions (Heitz et al. 2015).
