within UWCoSim.Examples;
model VehicleHarness
  "AUVKinematics with closed-form inputs, feeding a noise-free DVL and depth sounder"
  parameter Real psiRate(unit = "rad/s") = 0.01 "Heading rate: psi = psiRate*time";
  parameter Real aAmplitude(unit = "m/s2") = 0.001 "Acceleration amplitude";
  parameter Real aFrequency(unit = "rad/s") = 0.05 "a = aAmplitude*sin(aFrequency*time)";
  UWCoSim.AUVKinematics vehicle;
  UWCoSim.DVL dvl;
  UWCoSim.DepthSounder sounder;
equation
  // inputs as equations of time: rumoca 0.10 cannot take time-varying inputs at simulate()
  vehicle.psi = psiRate*time;
  vehicle.a = aAmplitude*sin(aFrequency*time);
  vehicle.w_x = 0;
  vehicle.w_y = 0;
  vehicle.w_vx = 0;
  vehicle.w_vy = 0;
  vehicle.w_psi = 0;
  vehicle.w_a = 0;
  connect(vehicle.vx, dvl.vx);
  connect(vehicle.vy, dvl.vy);
  dvl.e_vx = 0;
  dvl.e_vy = 0;
  dvl.w_bvx = 0;
  dvl.w_bvy = 0;
  dvl.w_scale = 0;
  dvl.altitude = sounder.altitude;
  connect(vehicle.x, sounder.x);
  connect(vehicle.y, sounder.y);
  sounder.e_h = 0;
  sounder.offset_h = 0;
  sounder.u_o = 0;
  sounder.e_o = 0;
  annotation (
    experiment(StartTime = 0, StopTime = 100, Tolerance = 1e-10, Interval = 0.1),
    Documentation(info = "<html>
<p>Inputs: <code>psi = 0.01*time</code>, <code>a = 0.001*sin(0.05*time)</code>, all noise
inputs 0. Simulated by <code>tests/test_modelica.py</code> and compared with
<code>uwcosim.models.vehicle.vehicle_ode</code> integrated by scipy.</p>
</html>"));
end VehicleHarness;
