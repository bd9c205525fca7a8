// The host of the test programs' precompiled headers (test/CMakeLists.txt): never run.
int main() { return 0; }
