# Sanitizer builds of thicket's own code (scripts/test --sanitize, CMakePresets.json):
#   THICKET_SANITIZE=address  AddressSanitizer (with LeakSanitizer) + UndefinedBehaviorSanitizer
#   THICKET_SANITIZE=thread   ThreadSanitizer
# The flags go to every target of this project, compile and link; the system libraries (LCM,
# glib, OpenCV, ...) are not rebuilt, so ASan and UBSan check our code and what it passes to them,
# and TSan sees their synchronization only where it goes through pthreads.
set(THICKET_SANITIZE "" CACHE STRING "Sanitizer build: empty (none), address (ASan+UBSan), thread")
set_property(CACHE THICKET_SANITIZE PROPERTY STRINGS "" address thread)

# Instrumented code runs several times slower: the long tests' time limits are multiplied by this.
set(THICKET_TEST_TIMEOUT_SCALE 1)
if(THICKET_SANITIZE STREQUAL "")
  return()
elseif(THICKET_SANITIZE STREQUAL "address")
  set(THICKET_TEST_TIMEOUT_SCALE 3)
  # -fno-sanitize-recover=all: a UBSan finding aborts the program, so the test that ran it fails.
  # -fno-sanitize=vptr: LCM 1.3.1's member-function LCM::subscribe (lcm-cpp-impl.hpp, a template,
  # so compiled into our code) keeps the handler object as void* and casts it back to the handler
  # class inside its callback; the vptr check calls that a member call on an object of the wrong
  # dynamic type on the first message that any program receives. The cast is LCM's, in a header
  # we cannot change, and the object is of the right type.
  set(thicket_sanitize_flags -fsanitize=address,undefined -fno-sanitize=vptr
                             -fno-sanitize-recover=all)
  # Eigen 3.4 stops trusting malloc's 16-byte alignment under ASan (__SANITIZE_ADDRESS__) and
  # switches to its own over-allocating aligned_malloc/free, which store the offset before the
  # block; PCL, Ceres and Open3D were built without ASan and use plain malloc/free. A point cloud
  # that libpcl_filters allocates and our code frees is then freed the other way (ASan: a read
  # 8 bytes before the block). ASan's malloc aligns to 16 bytes as glibc's does, so our code keeps
  # the libraries' choice.
  add_compile_definitions(EIGEN_MALLOC_ALREADY_ALIGNED=1)
elseif(THICKET_SANITIZE STREQUAL "thread")
  set(thicket_sanitize_flags -fsanitize=thread)
  set(THICKET_TEST_TIMEOUT_SCALE 10)
else()
  message(FATAL_ERROR "THICKET_SANITIZE is '${THICKET_SANITIZE}': use '', address or thread")
endif()
list(JOIN thicket_sanitize_flags " " shown)
message(STATUS "thicket: built with ${shown}")
# Frame pointers give the sanitizers' fast unwinder whole stacks. The instrumentation misleads
# GCC's -Wmaybe-uninitialized (GCC's manual, -fsanitize: "sanitizers tend to increase the rate of
# false positive warnings, most notably those around -Wmaybe-uninitialized"; GCC 12 flags an
# engaged std::optional in LocalPlanner::planToward): that warning stays an error in the normal
# build, the other warnings stay errors here too.
add_compile_options(${thicket_sanitize_flags} -fno-omit-frame-pointer -Wno-maybe-uninitialized)
add_link_options(${thicket_sanitize_flags})
