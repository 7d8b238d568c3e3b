# Dependencies that every part of thicket uses. Heavy libraries (OpenCV, PCL, Ceres, OMPL) are
# found by the modules that need them, so that the rest builds without their headers.

# LCM 1.3.1 on Debian has no CMake package (docs/design.md §7): find its pieces directly.
find_program(LCM_GEN lcm-gen REQUIRED)
find_library(LCM_LIBRARY lcm REQUIRED)
find_path(LCM_INCLUDE_DIR lcm/lcm-cpp.hpp REQUIRED)
find_file(LCM_JAR lcm.jar PATHS /usr/share/java /usr/local/share/java REQUIRED NO_DEFAULT_PATH)
find_file(JCHART2D_JAR jchart2d.jar PATHS /usr/share/java /usr/local/share/java NO_DEFAULT_PATH)

find_package(Java 17 REQUIRED COMPONENTS Runtime Development)
find_package(Threads REQUIRED)
find_package(Eigen3 3.4 REQUIRED NO_MODULE)
find_package(yaml-cpp REQUIRED)
find_package(nlohmann_json 3 REQUIRED)
find_package(CLI11 REQUIRED)
find_package(GTest REQUIRED)
find_package(benchmark REQUIRED)
