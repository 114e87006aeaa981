// The executable that owns the tests' precompiled header (tests/support/precompiled.hpp); it is
// built, never run.
int main() { return 0; }
