#pragma once
// Small valid files of a EuRoC sequence, the fixed part of the EuRoC fuzz targets: one file is
// replaced by the fuzzer's input, the others keep these contents.

namespace superdyna::fuzz {

inline constexpr const char* kCameraSensorYaml =
    "%YAML:1.0\n"
    "sensor_type: camera\n"
    "T_BS:\n"
    "  cols: 4\n"
    "  rows: 4\n"
    "  data: [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]\n"
    "rate_hz: 20\n"
    "resolution: [8, 6]\n"
    "camera_model: pinhole\n"
    "intrinsics: [4.0, 4.0, 4.0, 3.0]\n"
    "distortion_model: radial-tangential\n"
    "distortion_coefficients: [0.01, -0.02, 0.0, 0.0]\n";

inline constexpr const char* kImuSensorYaml =
    "sensor_type: imu\n"
    "T_BS:\n"
    "  cols: 4\n"
    "  rows: 4\n"
    "  data: [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]\n"
    "rate_hz: 200\n"
    "gyroscope_noise_density: 1.7e-04\n"
    "gyroscope_random_walk: 1.9e-05\n"
    "accelerometer_noise_density: 2.0e-3\n"
    "accelerometer_random_walk: 3.0e-3\n";

inline constexpr const char* kCameraCsv =
    "#timestamp [ns],filename\n"
    "1000000000,1.png\n"
    "1050000000,2.png\n";

inline constexpr const char* kImuCsv =
    "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
    "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n"
    "995000000,0.01,-0.02,0.03,9.8,0.1,-0.2\n"
    "1000000000,0.01,-0.02,0.03,9.8,0.1,-0.2\n"
    "1005000000,nan,-0.02,0.03,9.8,0.1,-0.2\n"
    "1055000000,0.01,-0.02,0.03,9.8,0.1,-0.2\n";

inline constexpr const char* kGroundTruthCsv =
    "#timestamp,p_x,p_y,p_z,q_w,q_x,q_y,q_z,v_x,v_y,v_z,bg_x,bg_y,bg_z,ba_x,ba_y,ba_z\n"
    "1000000000,0.1,0.2,0.3,1,0,0,0,0.5,0,0,0.001,0.002,0.003,0.01,0.02,0.03\n"
    "1050000000,0.2,0.2,0.3,0.7071068,0.7071068,0,0,0.5,0,0,0.001,0.002,0.003,0.01,0.02,0.03\n";

inline constexpr const char* kInstancesCsv =
    "# id,class,moving\n"
    "1,vehicle,1\n"
    "2,pedestrian,0\n"
    "3,unlabelled,0\n";

}  // namespace superdyna::fuzz
