"""The win64 toolchain both builds use (the Python FMUs' win64 loaders, fmus/build.py, and the C plant,
fmus/cplant_build.py): the MinGW-w64 cross compilers (the C one builds the DLLs; FMPy's CMake project
also asks for a C++ one) and the linker flags (libgcc kept out of a DLL's imports: KERNEL32 and msvcrt
only; no symbols)."""
MINGW_CC, MINGW_CXX = "x86_64-w64-mingw32-gcc", "x86_64-w64-mingw32-g++"
WIN64_LDFLAGS = "-static-libgcc -s"
