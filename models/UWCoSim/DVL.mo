within UWCoSim;
model DVL "Doppler velocity log, eq. (55) rows 1-2"
  import UWCoSim.Interfaces.RealInput;
  import UWCoSim.Interfaces.RealOutput;
  RealInput vx(unit = "m/s") "True velocity state vx";
  RealInput vy(unit = "m/s") "True velocity state vy";
  RealInput e_vx(unit = "m/s") "Measurement noise on vx";
  RealInput e_vy(unit = "m/s") "Measurement noise on vy";
  RealOutput vx_m(unit = "m/s") "Measured vx";
  RealOutput vy_m(unit = "m/s") "Measured vy";
equation
  vx_m = vx + e_vx;
  vy_m = vy + e_vy;
  annotation (Documentation(info = "<html>
<pre>
vx_m = vx + e_vx
vy_m = vy + e_vy
</pre>
</html>"));
end DVL;
