within UWCoSim;
model DVL "Doppler velocity log, eq. (55) rows 1-2, with bias and scale-factor random walks"
  import UWCoSim.Interfaces.RealInput;
  import UWCoSim.Interfaces.RealOutput;
  parameter Real maxAltitude(unit = "m") = 0 "Largest altitude with bottom lock (<= 0: always)";
  RealInput vx(unit = "m/s") "True velocity state vx";
  RealInput vy(unit = "m/s") "True velocity state vy";
  RealInput e_vx(unit = "m/s") "Measurement noise on vx";
  RealInput e_vy(unit = "m/s") "Measurement noise on vy";
  RealInput w_bvx(unit = "m/s2") "White noise driving the vx bias";
  RealInput w_bvy(unit = "m/s2") "White noise driving the vy bias";
  RealInput w_scale(unit = "1/s") "White noise driving the scale factor";
  RealInput altitude(unit = "m") "Altitude above the seafloor (bottom lock)";
  RealOutput vx_m(unit = "m/s") "Measured vx";
  RealOutput vy_m(unit = "m/s") "Measured vy";
  RealOutput bottom_lock "1 with bottom lock, 0 above maxAltitude";
  Real b_vx(unit = "m/s", start = 0, fixed = true) "Bias random walk on vx";
  Real b_vy(unit = "m/s", start = 0, fixed = true) "Bias random walk on vy";
  Real scale(start = 0, fixed = true) "Scale-factor error random walk";
equation
  der(b_vx) = w_bvx;
  der(b_vy) = w_bvy;
  der(scale) = w_scale;
  vx_m = (1 + scale)*vx + b_vx + e_vx;
  vy_m = (1 + scale)*vy + b_vy + e_vy;
  bottom_lock = if maxAltitude > 0 and altitude > maxAltitude then 0 else 1;
  annotation (Documentation(info = "<html>
<pre>
der(b) = w_b, der(scale) = w_scale        (random walks; 0 with the noise inputs at 0)
vx_m = (1 + scale)*vx + b_vx + e_vx
vy_m = (1 + scale)*vy + b_vy + e_vy
bottom_lock = 0 if maxAltitude &gt; 0 and altitude &gt; maxAltitude, else 1
</pre>
</html>"));
end DVL;
