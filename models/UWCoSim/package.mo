within;
package UWCoSim "Truth and process models of the uwcosim AUV navigation testbench"
  annotation (
    version = "0.1.0",
    Documentation(info = "<html>
<p>Modelica mirror of the models in <code>uwcosim.models</code> (CasADi), with the same
variable names as the project's FMUs: <code>AUVKinematics</code> (seed paper eq. 54),
<code>DVL</code> and <code>DepthSounder</code> (eq. 55) and the <code>ConstantVelocity</code>
process model of the filters. See <code>models/README.md</code> for the equations.</p>
<p>The package is self-contained (no Modelica Standard Library needed):
<code>UWCoSim.Interfaces</code> declares the <code>RealInput</code>/<code>RealOutput</code>
connectors with the same definitions as <code>Modelica.Blocks.Interfaces</code>.</p>
</html>"));
end UWCoSim;
