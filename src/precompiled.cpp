// The library target that owns the libraries' precompiled header (src/precompiled.hpp); its
// object is linked nowhere.
