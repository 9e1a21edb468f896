within UWCoSim;
model AUVKinematics "AUV planar kinematics of the seed paper, eq. (54)"
  import UWCoSim.Interfaces.RealInput;
  import UWCoSim.Interfaces.RealOutput;
  parameter Real x0(unit = "m") = 2000 "Initial east position";
  parameter Real y0(unit = "m") = 18000 "Initial north position";
  parameter Real vx0(unit = "m/s") = 0.5 "Initial velocity state vx";
  parameter Real vy0(unit = "m/s") = 0 "Initial velocity state vy";
  RealInput psi(unit = "rad") "Heading";
  RealInput a(unit = "m/s2") "Acceleration along the heading";
  RealInput w_x(unit = "m/s") "Process noise on der(x)";
  RealInput w_y(unit = "m/s") "Process noise on der(y)";
  RealInput w_vx(unit = "m/s2") "Process noise on der(vx)";
  RealInput w_vy(unit = "m/s2") "Process noise on der(vy)";
  RealInput w_psi(unit = "rad") "Control noise added to the heading";
  RealInput w_a(unit = "m/s2") "Control noise added to the acceleration";
  Real psi_v(unit = "rad") "Heading the vehicle follows: psi + w_psi";
  Real a_v(unit = "m/s2") "Acceleration the vehicle follows: a + w_a";
  RealOutput x(unit = "m", start = x0, fixed = true) "East position";
  RealOutput y(unit = "m", start = y0, fixed = true) "North position";
  RealOutput vx(unit = "m/s", start = vx0, fixed = true) "Velocity state vx";
  RealOutput vy(unit = "m/s", start = vy0, fixed = true) "Velocity state vy";
  RealOutput psi_out(unit = "rad") "Heading, passed through";
equation
  psi_v = psi + w_psi;
  a_v = a + w_a;
  der(x) = vx*cos(psi_v) - vy*sin(psi_v) + w_x;
  der(y) = vy*cos(psi_v) + vx*sin(psi_v) + w_y;
  der(vx) = a_v*cos(psi_v) + w_vx;
  der(vy) = a_v*sin(psi_v) + w_vy;
  psi_out = psi;
  annotation (Documentation(info = "<html>
<p>Seed paper eq. (54), reproduced as printed (the velocity state is rotated by psi for the
position rate while the acceleration is applied along psi):</p>
<pre>
der(x)  = vx*cos(psi) - vy*sin(psi) + w_x
der(y)  = vy*cos(psi) + vx*sin(psi) + w_y
der(vx) = a*cos(psi) + w_vx
der(vy) = a*sin(psi) + w_vy
</pre>
<p>Same variables as <code>fmus/AUVKinematics.fmu</code> and
<code>uwcosim.models.vehicle.vehicle_ode</code>.</p>
</html>"));
end AUVKinematics;
