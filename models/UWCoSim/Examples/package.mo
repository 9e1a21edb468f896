within UWCoSim;
package Examples "Closed-form test harnesses"
end Examples;
