// The 3D view's scripts, compiled in from files at configure time (see CMakeLists.txt):
// three.js r111 (Debian libjs-three, MIT licence), its OrbitControls and view3d.js. Every
// "</script" in them is written "<\/script" so that they can be inlined in <script> elements.
//
// Thread safety: constants.
#pragma once

namespace rephoto::report::internal {

extern const char* const kThreeJs;
extern const char* const kOrbitControlsJs;
extern const char* const kView3dJs;

}  // namespace rephoto::report::internal
